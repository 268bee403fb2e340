"""Train stable-baselines3 PPO (the seed's stack) on an echogym vector env.

The envs run in the echogym server; SB3 sees one ``VecEnv`` whose ``num_envs`` envs are
stepped with one shared-memory exchange (:class:`echogym.sb3.SB3VecEnv`), wrapped
in SB3's ``VecNormalize`` (observation and reward normalisation, as the seed used) and
``VecMonitor`` (episode returns and lengths). The seed's networks by default: [256, 128]
for both actor and critic.

    python examples/sb3_ppo.py --env-id echogym/PushCube-v0 --num-envs 16 \
        --total-timesteps 200000 --out runs/sb3-push

A server is started privately for this process if none runs (``echogym serve`` for a
long-lived one; ``ECHOGYM_SERVER`` picks it by name). Writes ``OUT/model.zip``,
``OUT/vecnormalize.pkl`` and ``OUT/eval.json`` (deterministic evaluation episodes).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from echogym.sb3 import SB3VecEnv


def evaluate(model: PPO, venv: VecNormalize, episodes: int) -> dict[str, float]:
    """Deterministic episodes on the training envs (normalisation frozen)."""
    venv.training = False
    venv.norm_reward = False
    obs = venv.reset()
    returns: list[float] = []
    successes: list[float] = []
    running = np.zeros(venv.num_envs)
    while len(returns) < episodes:
        action, _ = model.predict(obs, deterministic=True)
        obs, reward, done, infos = venv.step(action)
        running += reward
        for i in np.flatnonzero(done):
            returns.append(float(running[i]))
            successes.append(float(infos[i].get("is_success", False)))
            running[i] = 0.0
    return {
        "episodes": len(returns),
        "return_mean": float(np.mean(returns)),
        "success_rate": float(np.mean(successes)),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env-id", default="echogym/PushCube-v0")
    parser.add_argument("--env-config", type=json.loads, default={},
                        help="env config as a JSON object")
    parser.add_argument("--num-envs", type=int, default=16)
    parser.add_argument("--total-timesteps", type=int, default=200_000)
    parser.add_argument("--n-steps", type=int, default=256, help="steps per env per rollout")
    parser.add_argument("--batch-size", type=int, default=512)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=16)
    parser.add_argument("--out", default="runs/sb3")
    args = parser.parse_args(argv)

    torch.set_num_threads(1)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    venv = SB3VecEnv(args.env_id, args.num_envs, **args.env_config)
    venv.seed(args.seed)
    venv = VecNormalize(VecMonitor(venv), norm_obs=True, norm_reward=True, gamma=0.99)
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        policy_kwargs={"net_arch": {"pi": [256, 128], "vf": [256, 128]}},
        seed=args.seed,
        device="auto",
        verbose=0,
    )
    start = time.monotonic()
    model.learn(total_timesteps=args.total_timesteps)
    wall = time.monotonic() - start
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    result = {
        "env_id": args.env_id,
        "timesteps": int(model.num_timesteps),
        "wall_time_s": wall,
        "env_steps_per_s": model.num_timesteps / wall,
        **evaluate(model, venv, args.eval_episodes),
    }
    (out / "eval.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))
    venv.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
