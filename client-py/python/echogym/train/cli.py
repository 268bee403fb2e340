"""The training command line: ``python -m echogym.train`` / ``echogym-train``.

``--resume PATH`` continues a run: the checkpoint's settings, overridden by the flags
given (typically ``--total-frames``). ``--eval-only CHECKPOINT`` evaluates a checkpoint;
``--eval-only zero`` and ``--eval-only initial`` evaluate the zero-action and the
untrained policy of the same settings (the baselines in docs/training.md).
"""

from __future__ import annotations

import dataclasses
import json
import sys

from echogym.train.config import TrainConfig, build_parser, config_from_args


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; the exit code."""
    parser = build_parser()
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    from echogym.train.checkpoint import load_checkpoint, load_policy
    from echogym.train.evaluation import evaluate
    from echogym.train.networks import build_networks, zero_policy
    from echogym.train.ppo import PPOTrainer

    if args.resume:
        saved = TrainConfig.from_dict(load_checkpoint(args.resume)["config"])
        data = dataclasses.asdict(saved)
        for f in dataclasses.fields(TrainConfig):
            value = getattr(args, f.name, None)
            if value is not None:
                data[f.name] = value
        cfg = TrainConfig.from_dict(data)
    else:
        cfg = config_from_args(args)
    if args.eval_only:
        if args.eval_only == "zero":
            policy = zero_policy(cfg)
        elif args.eval_only == "initial":
            policy, _ = build_networks(cfg)
        else:
            policy, saved_cfg = load_policy(args.eval_only)
            explicit = {f.name: getattr(args, f.name) for f in dataclasses.fields(TrainConfig)
                        if getattr(args, f.name, None) is not None}
            cfg = TrainConfig.from_dict({**dataclasses.asdict(saved_cfg), **explicit})
        result = evaluate(policy, cfg)
        print(json.dumps({"policy": args.eval_only, "env_id": cfg.env_id, "seed": cfg.seed,
                          **result}, indent=2))
        return 0
    trainer = PPOTrainer(cfg, resume=args.resume)
    summary = trainer.train()
    print(json.dumps(summary, indent=2))
    return 0
