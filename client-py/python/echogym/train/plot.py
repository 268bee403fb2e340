"""Learning curves of a run: ``python -m echogym.train.plot LOGDIR --out curve.png``.

Draws, against env steps, the training episodes' return and success rate (smoothed over
``--smooth`` iterations) from ``progress.csv`` and the evaluation points from
``eval.csv`` (success rate; the force-band share for envs with a contact force), with
optional horizontal reference lines (``--baseline NAME=VALUE``) for baselines. Needs
matplotlib (``pip install 'echogym[plots]'``, part of ``[train]``).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from echogym.apps.plotting import pyplot


def _read(path: Path) -> dict[str, np.ndarray]:
    if not path.exists():
        return {}
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    out: dict[str, np.ndarray] = {}
    for key in rows[0] if rows else []:
        out[key] = np.array([float(r[key]) if r[key] not in ("", None) else np.nan for r in rows])
    return out


def _smooth(y: np.ndarray, window: int) -> np.ndarray:
    out = np.full_like(y, np.nan)
    for i in range(len(y)):
        chunk = y[max(0, i - window + 1) : i + 1]
        chunk = chunk[np.isfinite(chunk)]
        if chunk.size:
            out[i] = chunk.mean()
    return out


def plot_run(
    logdir: str | Path,
    out: str | Path,
    title: str | None = None,
    smooth: int = 10,
    baselines: dict[str, float] | None = None,
) -> Path:
    """Write the learning-curve PNG of ``logdir`` to ``out``."""
    plt = pyplot()
    logdir = Path(logdir)
    progress = _read(logdir / "progress.csv")
    evaluation = _read(logdir / "eval.csv")
    fig, (ax_ret, ax_score) = plt.subplots(1, 2, figsize=(11, 4))
    frames = progress["frames"] / 1e6
    ax_ret.plot(frames, _smooth(progress["episode_return"], smooth), color="C0")
    ax_ret.set_xlabel("env steps (millions)")
    ax_ret.set_ylabel("training episode return (env reward)")
    ax_ret.grid(alpha=0.3)
    if np.isfinite(progress.get("success_rate", np.array([np.nan]))).any():
        ax_score.plot(frames, _smooth(progress["success_rate"], smooth), color="C0",
                      label="training episodes: success")
    if evaluation:
        ef = evaluation["frames"] / 1e6
        if "force_band_share_mean" in evaluation:
            ax_score.plot(ef, evaluation["force_band_share_mean"], "o-", color="C3",
                          label="eval: share of the sweep within ±1 N")
            ax_score.plot(ef, evaluation["contact_share_mean"], "s--", color="C2",
                          label="eval: share of the sweep in contact")
        if "success_mean" in evaluation and "force_band_share_mean" not in evaluation:
            ax_score.plot(ef, evaluation["success_mean"], "o-", color="C3",
                          label="eval: success (deterministic)")
    for i, (name, value) in enumerate((baselines or {}).items()):
        ax_score.axhline(value, color=f"C{4 + i}", ls=":", label=name)
    ax_score.set_xlabel("env steps (millions)")
    ax_score.set_ylim(-0.02, 1.02)
    ax_score.grid(alpha=0.3)
    ax_score.legend(loc="lower right", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m echogym.train.plot", description=__doc__)
    parser.add_argument("logdir")
    parser.add_argument("--out", required=True)
    parser.add_argument("--title")
    parser.add_argument("--smooth", type=int, default=10)
    parser.add_argument("--baseline", action="append", default=[], metavar="NAME=VALUE")
    args = parser.parse_args(argv)
    baselines = {b.split("=")[0]: float(b.split("=")[1]) for b in args.baseline}
    print(plot_run(args.logdir, args.out, args.title, args.smooth, baselines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
