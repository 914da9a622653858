"""Seed 002: the CleanRL-style SAC v2 exercise (InvertedPendulum-v4), blanks filled in.

Networks: twin critics Q_1, Q_2 on concat(s, a) (256-256-1) with Polyak targets; actor trunk
256-256 with linear heads for the mean and the raw log std, squashed as
log_std = -5 + 0.5 * 7 * (tanh(x) + 1). Log-probability correction log(scale (1 - y^2) + 1e-6).
Losses: critic = MSE(Q_1) + MSE(Q_2); actor = mean(alpha log pi - min Q);
alpha = mean(-exp(log alpha) (log pi + H-bar)) with log pi resampled (no grad) from the actor
just updated. Policy delay: when global_step % policy_frequency == 0, policy_frequency actor
steps, each followed by an alpha step. Polyak (tau 0.005) of both critic targets every step.
Adam: critics and alpha at q_lr = 1e-3, actor at policy_lr = 3e-4.

The only change to the seed: `rsample()` and the `no_grad` resample take explicit standard
normal noise (u = mean + eps * std, which is what `Normal.rsample` computes). The hidden width
(the seed's 256) is a parameter, so the training-loop test can use small networks.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import torch.optim as optim

from references.common import grads

LOG_STD_MAX = 2
LOG_STD_MIN = -5


class ReplayBufferSamples(NamedTuple):
    """The fields of stable-baselines3's sample that the seed reads; rewards, dones (B, 1)."""
    observations: torch.Tensor
    actions: torch.Tensor
    next_observations: torch.Tensor
    dones: torch.Tensor
    rewards: torch.Tensor


class SoftQNetwork(nn.Module):
    def __init__(self, obs_size: int, action_size: int, hidden: int = 256):
        super().__init__()
        self.fc1 = nn.Linear(obs_size + action_size, hidden)
        self.fc2 = nn.Linear(hidden, hidden)
        self.fc3 = nn.Linear(hidden, 1)

    def forward(self, x, a):
        x = torch.cat([x, a], 1)
        x = F.relu(self.fc1(x))
        x = F.relu(self.fc2(x))
        x = self.fc3(x)
        return x

    def layers(self):
        return [self.fc1, self.fc2, self.fc3]


class Actor(nn.Module):
    def __init__(self, obs_size: int, action_size: int, low, high, hidden: int = 256):
        super().__init__()
        self.fc1 = nn.Linear(obs_size, hidden)
        self.fc2 = nn.Linear(hidden, hidden)
        self.fc_mean = nn.Linear(hidden, action_size)
        self.fc_logstd = nn.Linear(hidden, action_size)
        # action rescaling
        low, high = np.asarray(low, np.float32), np.asarray(high, np.float32)
        self.register_buffer("action_scale", torch.tensor((high - low) / 2.0, dtype=torch.float32))
        self.register_buffer("action_bias", torch.tensor((high + low) / 2.0, dtype=torch.float32))

    def forward(self, x):
        x = F.relu(self.fc1(x))
        x = F.relu(self.fc2(x))
        mean = self.fc_mean(x)
        log_std = self.fc_logstd(x)
        log_std = torch.tanh(log_std)
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (log_std + 1)  # From SpinUp
        return mean, log_std

    def get_action(self, x, eps):
        mean, log_std = self(x)
        std = log_std.exp()
        normal = torch.distributions.Normal(mean, std)
        x_t = mean + eps * std  # normal.rsample() with the noise given
        y_t = torch.tanh(x_t)
        action = y_t * self.action_scale + self.action_bias
        log_prob = normal.log_prob(x_t)
        # Enforcing Action Bound on log probability and mean
        log_prob -= torch.log(self.action_scale * (1 - y_t.pow(2)) + 1e-6)
        log_prob = log_prob.sum(1, keepdim=True)
        mean = torch.tanh(mean) * self.action_scale + self.action_bias
        return action, log_prob, mean

    def layers(self):
        return {"trunk": [self.fc1, self.fc2], "mean": [self.fc_mean], "log_std": [self.fc_logstd]}


class CleanRLSAC:
    """The seed's globals and the body of its `if global_step > learning_starts:` block."""

    def __init__(self, obs_size: int, action_size: int, low, high, seed: int = 0,
                 dtype=torch.float32, gamma=0.99, tau=0.005, policy_lr=3e-4, q_lr=1e-3,
                 policy_frequency=2, target_network_frequency=1, hidden=256):
        torch.manual_seed(seed)
        self.gamma, self.tau = gamma, tau
        self.policy_frequency = policy_frequency
        self.target_network_frequency = target_network_frequency
        self.target_entropy = -torch.prod(torch.Tensor((action_size,))).item()
        self.actor = Actor(obs_size, action_size, low, high, hidden).to(dtype)
        self.qf1 = SoftQNetwork(obs_size, action_size, hidden).to(dtype)
        self.qf2 = SoftQNetwork(obs_size, action_size, hidden).to(dtype)
        self.qf1_target = SoftQNetwork(obs_size, action_size, hidden).to(dtype)
        self.qf2_target = SoftQNetwork(obs_size, action_size, hidden).to(dtype)
        self.qf1_target.load_state_dict(self.qf1.state_dict())
        self.qf2_target.load_state_dict(self.qf2.state_dict())
        self.log_alpha = torch.zeros(1, requires_grad=True, dtype=dtype)
        self.alpha = self.log_alpha.exp().item()
        self.make_optimizers(policy_lr, q_lr)
        self.info = {}

    def make_optimizers(self, policy_lr=3e-4, q_lr=1e-3):
        """Fresh Adam states (call again after loading other weights into the modules)."""
        self.q_optimizer = optim.Adam(list(self.qf1.parameters()) + list(self.qf2.parameters()),
                                      lr=q_lr)
        self.actor_optimizer = optim.Adam(list(self.actor.parameters()), lr=policy_lr)
        self.a_optimizer = optim.Adam([self.log_alpha], lr=q_lr)

    # layout for references/transfer.py
    def networks(self):
        return {"actor": self.actor.layers(),
                "critic": [self.qf1.layers(), self.qf2.layers()],
                "critic_target": [self.qf1_target.layers(), self.qf2_target.layers()]}

    def get_action(self, obs, eps):
        """(action (B, A), log pi (B,)) for explicit noise eps (B, A)."""
        action, log_prob, _ = self.actor.get_action(obs, eps)
        return action, log_prob.view(-1)

    def update(self, data: ReplayBufferSamples, noise, global_step: int):
        """One pass of the seed's training block. noise: "critic" (B, A); "actor" and
        "temperature": sequences of policy_frequency arrays (B, A). `info` records each loss,
        the gradient of each backward pass (as modules holding the gradients) and log pi."""
        info = self.info = {"actor_loss": [], "alpha_loss": [], "actor_grad": [],
                            "alpha_grad": [], "actor_log_pi": [], "alpha_log_pi": []}
        actor, qf1, qf2 = self.actor, self.qf1, self.qf2
        gamma, tau = self.gamma, self.tau
        with torch.no_grad():
            next_state_actions, next_state_log_pi, _ = actor.get_action(data.next_observations,
                                                                        noise["critic"])
            qf1_next_target = self.qf1_target(data.next_observations, next_state_actions)
            qf2_next_target = self.qf2_target(data.next_observations, next_state_actions)
            min_qf_next_target = (torch.min(qf1_next_target, qf2_next_target)
                                  - self.alpha * next_state_log_pi)
            next_q_value = data.rewards.flatten() + (1 - data.dones.flatten()) * gamma * (
                min_qf_next_target).view(-1)

        qf1_a_values = qf1(data.observations, data.actions).view(-1)
        qf2_a_values = qf2(data.observations, data.actions).view(-1)
        qf1_loss = F.mse_loss(qf1_a_values, next_q_value)
        qf2_loss = F.mse_loss(qf2_a_values, next_q_value)
        qf_loss = qf1_loss + qf2_loss

        # optimize the critics
        self.q_optimizer.zero_grad()
        qf_loss.backward()
        info["critic_loss"] = qf_loss.item()
        info["critic_grad"] = [grads(qf1.layers()), grads(qf2.layers())]
        self.q_optimizer.step()

        if global_step % self.policy_frequency == 0:
            for k in range(self.policy_frequency):
                pi, log_pi, _ = actor.get_action(data.observations, noise["actor"][k])
                qf1_pi = qf1(data.observations, pi)
                qf2_pi = qf2(data.observations, pi)
                min_qf_pi = torch.min(qf1_pi, qf2_pi)
                actor_loss = ((self.alpha * log_pi) - min_qf_pi).mean()

                self.actor_optimizer.zero_grad()
                actor_loss.backward()
                info["actor_loss"].append(actor_loss.item())
                info["actor_grad"].append(grads(actor.layers()))
                info["actor_log_pi"].append(log_pi.detach().view(-1).clone())
                self.actor_optimizer.step()

                # Update alpha
                with torch.no_grad():
                    _, log_pi, _ = actor.get_action(data.observations, noise["temperature"][k])
                alpha_loss = (-self.log_alpha.exp() * (log_pi + self.target_entropy)).mean()

                self.a_optimizer.zero_grad()
                alpha_loss.backward()
                info["alpha_loss"].append(alpha_loss.item())
                info["alpha_grad"].append(self.log_alpha.grad.detach().clone())
                info["alpha_log_pi"].append(log_pi.view(-1).clone())
                self.a_optimizer.step()
                self.alpha = self.log_alpha.exp().item()

        # update the target networks
        if global_step % self.target_network_frequency == 0:
            for param, target_param in zip(qf1.parameters(), self.qf1_target.parameters()):
                target_param.data.copy_(tau * param.data + (1 - tau) * target_param.data)
            for param, target_param in zip(qf2.parameters(), self.qf2_target.parameters()):
                target_param.data.copy_(tau * param.data + (1 - tau) * target_param.data)
        return info


def make_batch(obs, action, reward, next_obs, terminated, dtype=torch.float32):
    """numpy arrays (rewards, terminated (B,)) -> the seed's batch, rewards and dones (B, 1)."""
    t = lambda x: torch.as_tensor(np.asarray(x), dtype=dtype)
    return ReplayBufferSamples(observations=t(obs), actions=t(action), next_observations=t(next_obs),
                               dones=t(terminated).view(-1, 1), rewards=t(reward).view(-1, 1))
