"""Seeds 000 and 003: SAC v1 with a value network V_psi and its Polyak target V_psi_bar, twin
critics Q_theta_1, Q_theta_2 without targets, a fixed temperature of 1 and a reward scale.

`learn` follows seed 000 ("SAC from scratch for the Inverted Pendulum", FranciscoRMendes):
    V step:  J_V = 0.5 * MSE(V_psi(s), min_i Q_i(s, a~) - log pi(a~|s)), a~ drawn without the
             reparameterisation (its own noise);
    pi step: J_pi = mean(log pi(a~|s) - min_i Q_i(s, a~)), a~ reparameterised (its own noise);
    Q step:  J_Q = 0.5 * MSE(Q_1, Q-hat) + 0.5 * MSE(Q_2, Q-hat),
             Q-hat = scale * r + gamma * V_psi_bar(s') with V_psi_bar(s') set to 0 where done;
    psi_bar <- tau psi + (1 - tau) psi_bar.
Each network has its own Adam (lr 3e-4 for all, "alpha" and "beta" in the seed); Q_1 and Q_2
each have their own, which is the same as one Adam over both (Adam is elementwise).

Seed 000 does not show its actor, critic and value classes; they are taken from seed 003:
Linear 256-256 trunks with PyTorch's default init, output layers (Q, V, mean, log std)
U(+-3e-3) for weight and bias, log std clamped to [-20, 2]. The log-probability is seed 000's
`sample_normal`: action = tanh(u) * max_action, log pi -= log(1 - action^2 + 1e-6) (which is the
epsilon correction only for max_action = 1, the Bullet pendulum's bound).

Seed 000 backpropagates J_V and J_pi through networks it does not step (the target of J_V is
not detached; J_pi reaches the critics); each optimiser's `zero_grad` before its own backward
clears those contributions, so every step uses the gradient of its own loss only. This is kept
as in the seed.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import torch.optim as optim
from torch.distributions import Normal

from references.common import grads


class ValueNetwork(nn.Module):
    def __init__(self, state_dim, hidden_dim=256, init_w=3e-3):
        super().__init__()
        self.linear1 = nn.Linear(state_dim, hidden_dim)
        self.linear2 = nn.Linear(hidden_dim, hidden_dim)
        self.linear3 = nn.Linear(hidden_dim, 1)
        self.linear3.weight.data.uniform_(-init_w, init_w)
        self.linear3.bias.data.uniform_(-init_w, init_w)

    def forward(self, state):
        x = F.relu(self.linear1(state))
        x = F.relu(self.linear2(x))
        x = self.linear3(x)
        return x

    def layers(self):
        return [self.linear1, self.linear2, self.linear3]


class SoftQNetwork(nn.Module):
    def __init__(self, num_inputs, num_actions, hidden_size=256, init_w=3e-3):
        super().__init__()
        self.linear1 = nn.Linear(num_inputs + num_actions, hidden_size)
        self.linear2 = nn.Linear(hidden_size, hidden_size)
        self.linear3 = nn.Linear(hidden_size, 1)
        self.linear3.weight.data.uniform_(-init_w, init_w)
        self.linear3.bias.data.uniform_(-init_w, init_w)

    def forward(self, state, action):
        x = torch.cat([state, action], 1)
        x = F.relu(self.linear1(x))
        x = F.relu(self.linear2(x))
        x = self.linear3(x)
        return x

    def layers(self):
        return [self.linear1, self.linear2, self.linear3]


class PolicyNetwork(nn.Module):
    """Seed 003's policy network with seed 000's `sample_normal`."""

    def __init__(self, num_inputs, num_actions, max_action, hidden_size=256, init_w=3e-3,
                 log_std_min=-20, log_std_max=2, reparam_noise=1e-6):
        super().__init__()
        self.log_std_min = log_std_min
        self.log_std_max = log_std_max
        self.reparam_noise = reparam_noise
        self.max_action = np.asarray(max_action, np.float32)
        self.linear1 = nn.Linear(num_inputs, hidden_size)
        self.linear2 = nn.Linear(hidden_size, hidden_size)
        self.mean_linear = nn.Linear(hidden_size, num_actions)
        self.mean_linear.weight.data.uniform_(-init_w, init_w)
        self.mean_linear.bias.data.uniform_(-init_w, init_w)
        self.log_std_linear = nn.Linear(hidden_size, num_actions)
        self.log_std_linear.weight.data.uniform_(-init_w, init_w)
        self.log_std_linear.bias.data.uniform_(-init_w, init_w)

    def forward(self, state):
        x = F.relu(self.linear1(state))
        x = F.relu(self.linear2(x))
        mean = self.mean_linear(x)
        log_std = self.log_std_linear(x)
        log_std = torch.clamp(log_std, self.log_std_min, self.log_std_max)
        return mean, log_std

    def sample_normal(self, state, eps, reparameterize=True):
        mu, log_std = self.forward(state)
        sigma = log_std.exp()
        probabilities = Normal(mu, sigma)

        if reparameterize:
            actions = mu + eps * sigma  # probabilities.rsample() with the noise given
        else:
            with torch.no_grad():
                actions = mu + eps * sigma  # probabilities.sample() with the noise given

        action = torch.tanh(actions) * torch.tensor(self.max_action, dtype=mu.dtype)
        log_probs = probabilities.log_prob(actions)
        log_probs -= torch.log(1 - action.pow(2) + self.reparam_noise)
        log_probs = log_probs.sum(1, keepdim=True)

        return action, log_probs

    def layers(self):
        return {"trunk": [self.linear1, self.linear2], "mean": [self.mean_linear],
                "log_std": [self.log_std_linear]}


class SoftActorCritic:
    """Seed 000's `SoftActorCritic` without its replay memory; `learn(sample, noise)` takes
    the processed sample (s_t, a_t_rb, r_t, s_t_plus_1, done) and the noise."""

    def __init__(self, input_dims, n_actions, max_action, gamma=0.99, tau=0.005,
                 alpha=3e-4, beta=3e-4, reward_scale=2, seed=0, dtype=torch.float32):
        torch.manual_seed(seed)
        self.gamma = gamma
        self.tau = tau
        self.alpha_lr, self.beta_lr = alpha, beta
        self.pi_phi = PolicyNetwork(input_dims, n_actions, max_action).to(dtype)
        self.Q_theta_1 = SoftQNetwork(input_dims, n_actions).to(dtype)
        self.Q_theta_2 = SoftQNetwork(input_dims, n_actions).to(dtype)
        self.V_psi = ValueNetwork(input_dims).to(dtype)
        self.V_psi_bar = ValueNetwork(input_dims).to(dtype)
        self.scale = reward_scale
        self.update_psi_bar_using_psi(tau=1)
        self.make_optimizers()
        self.info = {}

    def make_optimizers(self):
        """Fresh Adam states (call again after loading other weights into the modules)."""
        self.pi_phi.optimizer = optim.Adam(self.pi_phi.parameters(), lr=self.alpha_lr)
        self.Q_theta_1.optimizer = optim.Adam(self.Q_theta_1.parameters(), lr=self.beta_lr)
        self.Q_theta_2.optimizer = optim.Adam(self.Q_theta_2.parameters(), lr=self.beta_lr)
        self.V_psi.optimizer = optim.Adam(self.V_psi.parameters(), lr=self.beta_lr)

    # layout for references/transfer.py
    def networks(self):
        return {"actor": self.pi_phi.layers(),
                "critic": [self.Q_theta_1.layers(), self.Q_theta_2.layers()],
                "value": self.V_psi.layers(), "value_target": self.V_psi_bar.layers()}

    def get_action(self, obs, eps):
        """(action (B, A), log pi (B,)) for explicit noise eps (B, A)."""
        action, log_prob = self.pi_phi.sample_normal(obs, eps, reparameterize=True)
        return action, log_prob.view(-1)

    def update_psi_bar_using_psi(self, tau=None):
        if tau is None:
            tau = self.tau
        psi_bar = self.V_psi_bar.named_parameters()
        psi = self.V_psi.named_parameters()
        target_value_state_dict = dict(psi_bar)
        value_state_dict = dict(psi)
        for name in value_state_dict:
            value_state_dict[name] = (tau * value_state_dict[name].clone()
                                      + (1 - tau) * target_value_state_dict[name].clone())
        self.V_psi_bar.load_state_dict(value_state_dict)

    def learn(self, sample, noise):
        """One call of seed 000's `learn`; noise: "value" and "actor", each (B, A). `info`
        records each loss, the gradient of each backward pass and log pi."""
        s_t, a_t_rb, r_t, s_t_plus_1, done = sample
        info = self.info = {}

        V_psi_s_t = self.V_psi(s_t).view(-1)
        V_psi_bar_s_t_plus_1 = self.V_psi_bar(s_t_plus_1).view(-1)
        V_psi_bar_s_t_plus_1[done] = 0.0

        # V step
        a_t_D, log_pi_t_D = self.pi_phi.sample_normal(s_t, noise["value"], reparameterize=False)
        log_pi_t_D = log_pi_t_D.view(-1)
        Q_theta_1_s_t_a_t_D = self.Q_theta_1.forward(s_t, a_t_D)
        Q_theta_2_s_t_a_t_D = self.Q_theta_2.forward(s_t, a_t_D)
        Q_theta_min_s_t_a_t_D = torch.min(Q_theta_1_s_t_a_t_D, Q_theta_2_s_t_a_t_D)
        Q_theta_min_s_t_a_t_D = Q_theta_min_s_t_a_t_D.view(-1)

        self.V_psi.optimizer.zero_grad()
        J_V_psi = 0.5 * F.mse_loss(V_psi_s_t, Q_theta_min_s_t_a_t_D - log_pi_t_D)
        J_V_psi.backward(retain_graph=True)
        info["value_loss"] = J_V_psi.item()
        info["value_grad"] = grads(self.V_psi.layers())
        self.V_psi.optimizer.step()

        # pi step
        a_t_D, log_pi_t_D = self.pi_phi.sample_normal(s_t, noise["actor"], reparameterize=True)
        log_pi_t_D = log_pi_t_D.view(-1)
        Q_theta_1_s_t_a_t_D = self.Q_theta_1.forward(s_t, a_t_D)
        Q_theta_2_s_t_a_t_D = self.Q_theta_2.forward(s_t, a_t_D)
        Q_theta_min_s_t_a_t_D = torch.min(Q_theta_1_s_t_a_t_D, Q_theta_2_s_t_a_t_D)
        Q_theta_min_s_t_a_t_D = Q_theta_min_s_t_a_t_D.view(-1)
        J_pi_phi = torch.mean(log_pi_t_D - Q_theta_min_s_t_a_t_D)
        self.pi_phi.optimizer.zero_grad()
        J_pi_phi.backward(retain_graph=True)
        info["actor_loss"] = J_pi_phi.item()
        info["actor_grad"] = grads(self.pi_phi.layers())
        info["actor_log_pi"] = log_pi_t_D.detach().clone()
        self.pi_phi.optimizer.step()

        # Q step
        self.Q_theta_1.optimizer.zero_grad()
        self.Q_theta_2.optimizer.zero_grad()
        Q_hat_s_t = self.scale * r_t + self.gamma * V_psi_bar_s_t_plus_1
        Q_theta_1_s_t_rb_at = self.Q_theta_1.forward(s_t, a_t_rb).view(-1)
        Q_theta_2_s_t_rb_at = self.Q_theta_2.forward(s_t, a_t_rb).view(-1)
        J_Q_theta_1_loss = 0.5 * F.mse_loss(Q_theta_1_s_t_rb_at, Q_hat_s_t)
        J_Q_theta_2_loss = 0.5 * F.mse_loss(Q_theta_2_s_t_rb_at, Q_hat_s_t)
        J_Q_theta_12 = J_Q_theta_1_loss + J_Q_theta_2_loss
        J_Q_theta_12.backward()
        info["critic_loss"] = J_Q_theta_12.item()
        info["critic_grad"] = [grads(self.Q_theta_1.layers()), grads(self.Q_theta_2.layers())]
        self.Q_theta_1.optimizer.step()
        self.Q_theta_2.optimizer.step()

        # V-bar
        self.update_psi_bar_using_psi(tau=None)
        return info

    update = learn


def make_batch(obs, action, reward, next_obs, terminated, dtype=torch.float32):
    """numpy arrays -> seed 000's processed sample (s_t, a_t_rb, r_t, s_t_plus_1, done), done a
    bool tensor (B,)."""
    t = lambda x: torch.as_tensor(np.asarray(x), dtype=dtype)
    return t(obs), t(action), t(reward), t(next_obs), torch.as_tensor(np.asarray(terminated) > 0.5)
