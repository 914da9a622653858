"""Seed 001: the Pendulum-v1 notebook's SAC v2, as written there.

Networks (hidden_dim 64 in the notebook's run): twin critic `QNetwork` with two 3-hidden-layer
MLPs on concat(s, a); `PolicyNetwork` with separate 3-hidden-layer MLPs for the mean and the
log std, log std clamped to [-20, 2]; every Linear Xavier-uniform (gain 1) with zero bias.
The critic target is a separately initialised `QNetwork` (the notebook does not copy the
critic's weights into it). Log-probability correction log(scale (1 - y^2) + 1e-6).
Update order: critic (sum of the two MSEs) -> policy (mean(alpha log pi - min Q)) -> alpha
(-(log_alpha * (log pi + H-bar).detach()).mean() with the log pi of the policy step, i.e. of
the actor before its update) -> alpha = exp(log_alpha) -> Polyak (tau 0.005) of the critic
target. alpha starts at 0.5 while log_alpha starts at 0. All Adam lr 3e-4.

The only change to the notebook: `rsample()` takes explicit standard normal noise
(u = mean + eps * std, which is what `Normal.rsample` computes), and `update` takes the batch
instead of drawing it from the memory.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import torch.optim as optim
from torch.distributions import Normal

from references.common import grads

LOG_SIG_MIN = -20
LOG_SIG_MAX = 2


def weights_init_(m):
    if isinstance(m, nn.Linear):
        torch.nn.init.xavier_uniform_(m.weight, gain=1)
        torch.nn.init.constant_(m.bias, 0)


def _linears(sequential):
    return [m for m in sequential if isinstance(m, nn.Linear)]


class QNetwork(nn.Module):
    def __init__(self, num_inputs, num_actions, hidden_dim):
        super().__init__()
        self.q1 = nn.Sequential(
            nn.Linear(num_inputs + num_actions, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, 1))
        self.q2 = nn.Sequential(
            nn.Linear(num_inputs + num_actions, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, 1))
        self.apply(weights_init_)

    def forward(self, state, action):
        x1 = self.q1(torch.cat([state, action], 1))
        x2 = self.q2(torch.cat([state, action], 1))
        return x1, x2

    def layers(self):
        return [_linears(self.q1), _linears(self.q2)]


class PolicyNetwork(nn.Module):
    def __init__(self, num_inputs, num_actions, hidden_dim, low, high):
        super().__init__()
        self.mean = nn.Sequential(
            nn.Linear(num_inputs, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, num_actions))
        self.log_std = nn.Sequential(
            nn.Linear(num_inputs, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, hidden_dim), nn.ReLU(),
            nn.Linear(hidden_dim, num_actions))
        self.apply(weights_init_)
        low, high = np.asarray(low, np.float32), np.asarray(high, np.float32)
        self.action_scale = torch.tensor((high - low) / 2.)
        self.action_bias = torch.tensor((high + low) / 2.)

    def forward(self, state):
        mean = self.mean(state)
        log_std = self.log_std(state)
        log_std = torch.clamp(log_std, min=LOG_SIG_MIN, max=LOG_SIG_MAX)
        return mean, log_std

    def sample(self, state, eps):
        mean, log_std = self.forward(state)
        std = log_std.exp()
        normal = Normal(mean, std)
        action = mean + eps * std  # normal.rsample() with the noise given
        compressed_action = torch.tanh(action)
        scaled_action = compressed_action * self.action_scale + self.action_bias
        log_prob = normal.log_prob(action)
        # We add a small constant to the log probability to prevent numerical instability
        log_prob = log_prob - torch.log(self.action_scale * (1 - compressed_action.pow(2)) + 1e-6)
        log_prob = log_prob.sum(dim=-1, keepdim=True)
        mean = torch.tanh(mean) * self.action_scale + self.action_bias
        return scaled_action, log_prob, mean

    def to(self, *args, **kwargs):
        self.action_scale = self.action_scale.to(*args, **kwargs)
        self.action_bias = self.action_bias.to(*args, **kwargs)
        return super().to(*args, **kwargs)

    def layers(self):
        return {"mean_net": _linears(self.mean), "log_std_net": _linears(self.log_std)}


class SAC:
    def __init__(self, num_inputs, num_actions, low, high, hidden_dim=64, seed=1,
                 dtype=torch.float32):
        torch.manual_seed(seed)
        self.critic = QNetwork(num_inputs, num_actions, hidden_dim).to(dtype)
        self.critic_target = QNetwork(num_inputs, num_actions, hidden_dim).to(dtype)
        self.policy = PolicyNetwork(num_inputs, num_actions, hidden_dim, low, high).to(dtype)
        self.gamma = 0.99
        self.tau = 0.005
        self.alpha = 0.5
        self.target_entropy = -num_actions
        self.log_alpha = torch.zeros(1, requires_grad=True, dtype=dtype)
        self.make_optimizers()
        self.info = {}

    def make_optimizers(self):
        """Fresh Adam states (call again after loading other weights into the modules)."""
        self.critic_optim = optim.Adam(self.critic.parameters(), lr=3e-4)
        self.policy_optim = optim.Adam(self.policy.parameters(), lr=3e-4)
        self.alpha_optim = optim.Adam([self.log_alpha], lr=3e-4)

    # layout for references/transfer.py
    def networks(self):
        return {"actor": self.policy.layers(), "critic": self.critic.layers(),
                "critic_target": self.critic_target.layers()}

    def get_action(self, obs, eps):
        """(action (B, A), log pi (B,)) for explicit noise eps (B, A)."""
        action, log_prob, _ = self.policy.sample(obs, eps)
        return action, log_prob.view(-1)

    def update(self, batch, noise):
        """The notebook's `update` on batch = (states, actions, next_states, rewards, dones),
        rewards and dones (B,); noise: "critic" and "actor", each (B, A). `info` records each
        loss, the gradient of each backward pass and log pi."""
        states, actions, next_states, rewards, dones = batch
        rewards = rewards.unsqueeze(1)
        dones = dones.unsqueeze(1)
        info = self.info = {}

        # update critic
        with torch.no_grad():
            next_action, next_log_pi, _ = self.policy.sample(next_states, noise["critic"])
            q1_target, q2_target = self.critic_target(next_states, next_action)
            q_target = torch.min(q1_target, q2_target) - self.alpha * next_log_pi
            next_target_Q = rewards + ((1 - dones) * self.gamma * (q_target))
        q1, q2 = self.critic(states, actions)
        q1_loss = F.mse_loss(q1, next_target_Q)
        q2_loss = F.mse_loss(q2, next_target_Q)
        q_loss = q1_loss + q2_loss

        self.critic_optim.zero_grad()
        q_loss.backward()
        info["critic_loss"] = q_loss.item()
        info["critic_grad"] = grads(self.critic.layers())
        self.critic_optim.step()

        # update policy
        pi, log_pi, _ = self.policy.sample(states, noise["actor"])
        q1_pi, q2_pi = self.critic(states, pi)
        min_q_pi = torch.min(q1_pi, q2_pi)
        policy_loss = (self.alpha * log_pi - min_q_pi).mean()

        self.policy_optim.zero_grad()
        policy_loss.backward()
        info["actor_loss"] = policy_loss.item()
        info["actor_grad"] = grads(self.policy.layers())
        info["actor_log_pi"] = log_pi.detach().view(-1).clone()
        self.policy_optim.step()

        # update alpha
        alpha_loss = -(self.log_alpha * (log_pi + self.target_entropy).detach()).mean()

        self.alpha_optim.zero_grad()
        alpha_loss.backward()
        info["alpha_loss"] = alpha_loss.item()
        info["alpha_grad"] = self.log_alpha.grad.detach().clone()
        self.alpha_optim.step()

        self.alpha = self.log_alpha.exp()

        # update target network
        for target_param, param in zip(self.critic_target.parameters(), self.critic.parameters()):
            target_param.data.copy_(target_param.data * (1.0 - self.tau) + param.data * self.tau)
        return info


def make_batch(obs, action, reward, next_obs, terminated, dtype=torch.float32):
    """numpy arrays -> the notebook's (states, actions, next_states, rewards, dones) tensors
    (`torch.FloatTensor` of the memory's arrays; double in float64 runs)."""
    t = lambda x: torch.as_tensor(np.asarray(x), dtype=dtype)
    return t(obs), t(action), t(next_obs), t(reward), t(terminated)
