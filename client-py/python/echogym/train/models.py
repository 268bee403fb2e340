"""The PPO networks: a running observation normaliser, a Gaussian actor with a
state-independent log standard deviation (stable-baselines3's default, so the seed's
[256, 128] networks behave as they did there) and a value network.

The normaliser lives inside the networks as buffers, so a checkpoint carries it and the
collectors' weight sync (``TensorDict.from_module``, which includes buffers) ships it to
every worker process with the weights; the trainer updates it only between PPO updates,
so the log-probabilities stored at collection time stay valid for the update.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase
from torch import nn
from torchrl.data import Bounded
from torchrl.envs.utils import ExplorationType, exploration_type
from torchrl.modules import IndependentNormal, ProbabilisticActor, ValueOperator

_ACTIVATIONS = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


class RunningNorm(nn.Module):
    """``(x − mean) / std`` with running moments (parallel Welford), clipped to ±``clip``."""

    def __init__(self, size: int, clip: float = 10.0, eps: float = 1e-8) -> None:
        super().__init__()
        self.clip = clip
        self.eps = eps
        self.register_buffer("mean", torch.zeros(size))
        self.register_buffer("var", torch.ones(size))
        self.register_buffer("count", torch.tensor(1e-4, dtype=torch.float64))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return ((x - self.mean) / torch.sqrt(self.var + self.eps)).clamp(-self.clip, self.clip)

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        """Fold a batch ``[..., size]`` into the moments (in place: views stay valid)."""
        x = x.reshape(-1, self.mean.numel()).to(self.mean.device, torch.float64)
        n = x.shape[0]
        if n == 0:
            return
        batch_mean = x.mean(0)
        batch_var = x.var(0, unbiased=False)
        total = self.count + n
        delta = batch_mean - self.mean.double()
        mean = self.mean.double() + delta * n / total
        m2 = self.var.double() * self.count + batch_var * n + delta.square() * self.count * n / total
        self.mean.copy_(mean.float())
        self.var.copy_((m2 / total).float())
        self.count.copy_(total)


def mlp(inputs: int, hidden: Sequence[int], outputs: int, activation: str) -> nn.Sequential:
    """``inputs → hidden... → outputs`` with ``activation`` between layers."""
    act = _ACTIVATIONS[activation]
    layers: list[nn.Module] = []
    size = inputs
    for width in hidden:
        layers += [nn.Linear(size, width), act()]
        size = width
    layers.append(nn.Linear(size, outputs))
    return nn.Sequential(*layers)


class GaussianPolicyNet(nn.Module):
    """Normalised observation → (loc, scale) of a diagonal Gaussian."""

    def __init__(
        self, obs_size: int, action_size: int, hidden: Sequence[int], activation: str, log_std: float
    ) -> None:
        super().__init__()
        self.norm = RunningNorm(obs_size)
        self.body = mlp(obs_size, hidden, action_size, activation)
        self.log_std = nn.Parameter(torch.full((action_size,), float(log_std)))
        # Small last layer: the initial policy's mean is ≈ 0 (SB3 and the PPO papers do this).
        last = self.body[-1]
        assert isinstance(last, nn.Linear)
        nn.init.orthogonal_(last.weight, gain=0.01)
        nn.init.zeros_(last.bias)

    def forward(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        loc = self.body(self.norm(observation))
        scale = self.log_std.clamp(-5.0, 2.0).exp().expand_as(loc)
        return loc, scale

    def loc(self, observation: torch.Tensor) -> torch.Tensor:
        """``forward``'s ``loc``, the same operations without the per-module call
        overhead (module hooks are not run; echogym registers none)."""
        x = self.norm.forward(observation)
        for layer in self.body:
            x = layer.forward(x)
        return x


class ValueNet(nn.Module):
    """Normalised observation → state value."""

    def __init__(self, obs_size: int, hidden: Sequence[int], activation: str) -> None:
        super().__init__()
        self.norm = RunningNorm(obs_size)
        self.body = mlp(obs_size, hidden, 1, activation)

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        return self.body(self.norm(observation))


def make_actor(
    obs_size: int,
    action_spec: Bounded,
    hidden: Sequence[int],
    activation: str = "tanh",
    log_std: float = 0.0,
) -> ProbabilisticActor:
    """The stochastic policy: ``"observation"`` → ``"action"`` (+ ``"action_log_prob"``).

    Actions are unsquashed Gaussian samples (the server clips them to the action bounds,
    as SB3 does); the deterministic action is the mean.
    """
    net = GaussianPolicyNet(obs_size, action_spec.shape[-1], hidden, activation, log_std)
    module = TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"])
    return ProbabilisticActor(
        module,
        spec=action_spec,
        in_keys=["loc", "scale"],
        distribution_class=IndependentNormal,
        return_log_prob=True,
    )


class GaussianSampler(TensorDictModuleBase):
    """The actor's collection path in one module: ``"observation"`` → ``"loc"``,
    ``"scale"``, ``"action"``, ``"action_log_prob"``, as :func:`make_actor`'s
    ``ProbabilisticActor`` computes them, without its per-call tensordict plumbing
    (docs/results/performance-client.md: the ``ProbabilisticActor`` call costs ≈ 4× this).

    It holds the actor's own ``module`` under the same attribute name, so its parameters
    *are* the actor's and ``TensorDict.from_module(actor)`` weights load into it
    unchanged (collectors' weight sync). Random interaction samples the Gaussian
    (``loc + scale · ε``: the actor's distribution, not its exact draws for a seed);
    deterministic, mode and mean give ``loc``. ``loc`` is computed by the actor's own
    layers with the same operations (bit-identical); the log-probability is
    ``log N(action; loc, scale)`` summed over the action's elements, computed from ``ε``
    (``-ε²/2 - log scale - log √2π``; equal to ``IndependentNormal``'s to float rounding).
    """

    in_keys = ["observation"]
    out_keys = ["loc", "scale", "action", "action_log_prob"]

    def __init__(self, actor: ProbabilisticActor) -> None:
        super().__init__()
        self.module = actor.module
        if not isinstance(self.module[0].module, GaussianPolicyNet):
            raise TypeError("GaussianSampler needs an actor made by make_actor")

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        # Parameters are looked up on every call: weight sync may replace them.
        net = self.module[0].module
        loc = net.loc(tensordict.get("observation"))
        log_std = net.log_std.clamp(-5.0, 2.0)
        scale = log_std.exp().expand_as(loc)
        # Σ log scale + n·log √2π: the log-density's constant part.
        constant = log_std.sum() + loc.shape[-1] * _HALF_LOG_2PI
        if exploration_type() in (None, ExplorationType.RANDOM):
            noise = torch.randn_like(loc)
            action = loc + scale * noise
            log_prob = noise.square().sum(-1).mul_(-0.5).sub_(constant)
        else:
            action = loc
            log_prob = (-constant).expand(loc.shape[:-1]).clone()
        if type(tensordict) is TensorDict:
            # Entries of the right batch shape by construction: set without validation
            # (what torchrl does for entries it builds; tensordict is pinned to 0.14.x).
            for key, value in (("loc", loc), ("scale", scale), ("action", action),
                               ("action_log_prob", log_prob)):
                tensordict._set_str(key, value, validated=True, inplace=False,
                                    non_blocking=False)
        else:
            tensordict.set("loc", loc)
            tensordict.set("scale", scale)
            tensordict.set("action", action)
            tensordict.set("action_log_prob", log_prob)
        return tensordict


_HALF_LOG_2PI = 0.5 * math.log(2 * math.pi)


def make_critic(obs_size: int, hidden: Sequence[int], activation: str = "tanh") -> ValueOperator:
    """The value network: ``"observation"`` → ``"state_value"``."""
    return ValueOperator(ValueNet(obs_size, hidden, activation), in_keys=["observation"])


def norms(module: nn.Module) -> list[RunningNorm]:
    """Every :class:`RunningNorm` inside ``module``."""
    return [m for m in module.modules() if isinstance(m, RunningNorm)]
