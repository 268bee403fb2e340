"""The plots of a calibration report (``echogym calibrate DATASET --out OUT`` draws them
after the Rust calibration succeeds; :func:`plot_report` draws them for any ``OUT``).

Drawn from ``OUT/report.json``, ``OUT/replay/*.csv`` and ``OUT/thesis_method.csv`` (read
with :mod:`echogym.calibration`):

- ``residual_map.png``: where the baseline misses (share of the residual energy by phase,
  depth, velocity and frequency band, and the worst time spans);
- ``heldout_before_after.png``: measured force against the baseline and the calibrated
  simulator on every held-out recording;
- ``seed_regression.png``: the seed's F/r vs v/r regression per site.

Needs matplotlib (``pip install 'echogym[plots]'``).
"""

from __future__ import annotations

from pathlib import Path

from echogym.apps.plotting import pyplot
from echogym.calibration import load_replay, load_report, load_thesis_method

__all__ = ["plot_report"]


def plot_report(out: str | Path) -> list[Path]:
    """Draw the report's PNGs into ``out``; the paths written."""
    plt = pyplot()
    out = Path(out)
    report = load_report(out)
    written = []

    shares = report["mismatch_shares"]
    fig, axes = plt.subplots(1, 5, figsize=(17, 3.6))
    for ax, key, title in zip(axes[:4], ["by_phase", "by_depth", "by_velocity", "by_frequency"],
                              ["phase", "depth", "velocity", "frequency"]):
        rows = shares[key]
        ax.barh([r["label"] for r in rows], [100 * r["share"] for r in rows], color="tab:red")
        ax.set_title(f"residual energy by {title}", fontsize=9)
        ax.set_xlabel("% of Σr²", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.invert_yaxis()
    spans = report["mismatch"][:8]
    axes[4].barh([f"{s['recording'][:18]} {s['t_start']:.0f}-{s['t_end']:.0f}s" for s in spans],
                 [100 * s["share"] for s in spans], color="tab:orange")
    axes[4].set_title("worst 2 s spans", fontsize=9)
    axes[4].tick_params(labelsize=7)
    axes[4].invert_yaxis()
    fig.suptitle(f"Where the baseline misses (held-out RMSE {report['baseline']['rmse_heldout_n']:.3f} N, "
                 f"noise ≈ {report['noise_floor_n']:.3f} N)", fontsize=10)
    written.append(_save(plt, fig, out / "residual_map.png"))

    held = report["split"]["heldout"]
    fig, axes = plt.subplots(len(held), 1, figsize=(10, 2.4 * len(held)), squeeze=False)
    for ax, file in zip(axes[:, 0], held):
        r = load_replay(out, file)
        ax.plot(r["t"], r["fz_measured"], color="0.6", lw=0.8, label="measured")
        ax.plot(r["t"], r["fz_baseline"], color="tab:blue", lw=1.0, label="baseline")
        ax.plot(r["t"], r["fz_calibrated"], color="tab:red", lw=1.0, label="calibrated")
        ax.set_title(file, fontsize=8)
        ax.set_ylabel("fz [N]", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    names = ", ".join(e["name"] for e in report["effects"]) or "none"
    imp = report["improvement"]
    fig.suptitle(f"Held-out recordings: RMSE {imp['heldout_rmse_before_n']:.3f} → "
                 f"{imp['heldout_rmse_after_n']:.3f} N (effects added: {names})", fontsize=10)
    written.append(_save(plt, fig, out / "heldout_before_after.png"))

    points = load_thesis_method(out)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for fit in report["thesis_method"]:
        xs, ys = points.get(fit["site"], ([], []))
        dots = ax.scatter(xs, ys, s=3, alpha=0.3)
        if xs:
            lo, hi = min(xs), max(xs)
            ax.plot([lo, hi], [fit["intercept"] + fit["slope"] * lo, fit["intercept"] + fit["slope"] * hi],
                    color=dots.get_facecolor()[0], lw=1.5,
                    label=f"{fit['site']}: k={fit['intercept']:.0f}, b={fit['slope']:.1f}, r²={fit['r2']:.2f}")
    ax.set_xlabel("v / r [1/s]")
    ax.set_ylabel("F / r [N/m]")
    ax.set_title("The thesis's method: F/r regressed on v/r per site", fontsize=10)
    ax.legend(fontsize=7)
    written.append(_save(plt, fig, out / "seed_regression.png"))
    return written


def _save(plt, fig, path: Path) -> Path:
    """Lay out, write at 110 dpi and close `fig`; the path written."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
