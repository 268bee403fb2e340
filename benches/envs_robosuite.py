#!/usr/bin/env python3
"""robosuite side of echogym's peer environment benchmark: how fast robosuite's
env loop runs, which is what a user who picks robosuite instead of echogym gets.

Usage (from the repo root; create the venv first with ``benches/peers-venv``)::

    benches/.venv-peers/bin/python benches/envs_robosuite.py --seconds 3 --repeats 3

Prints ONE JSON object on stdout; every progress / diagnostic line goes to stderr.

What it measures (one process, one env at a time, robosuite 1.5.2 on MuJoCo):

(a) ``lift_panda_osc_20hz``: env-steps/s of ``Lift`` with a ``Panda`` arm and the
    OSC_POSE arm controller at ``control_freq=20``. robosuite's default setup, so
    each env step runs int(0.05 s / 0.002 s) = 25 MuJoCo steps, with the OSC
    torques recomputed before every one of them.
(b) ``lift_ur5e_osc_500hz``: the same task with a ``UR5e`` arm at
    ``control_freq=500``, i.e. one MuJoCo step per env step. This is the closest
    robosuite gets to a high-rate control loop like echogym's, and it mostly
    measures robosuite's per-step Python overhead (controller, observables,
    reward).
(c) ``lift_reset_ms``: the wall time of ``env.reset()`` for the env of (a).
    robosuite's default ``hard_reset=True`` rebuilds the MJCF model and the MjSim
    on every reset (``--no-hard-reset`` measures the soft reset instead). One
    untimed ``env.step`` runs between two resets, the way an episode loop would.

Setup shared by all measurements:
* No renderer, no offscreen renderer and no camera observations
  (``has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False``).
  Object observations stay on, as in robosuite's defaults, so every step still
  computes the full proprio + object observation dict and the reward.
* Controller: ``robosuite.load_composite_controller_config(controller="BASIC")``.
  That is robosuite 1.5's composite controller: every arm gets the OSC_POSE part
  controller (delta pose input, kp 150, critically damped), and the gripper gets
  GRIP. The script checks that each arm's part controller really is
  ``OSC_POSE``.
* ``ignore_done=True``, so an episode never ends inside a timed window. Every
  repeat starts from a fresh (untimed) ``env.reset()``, so all repeats time the
  same kind of trajectory.
* Actions: uniform random in ``env.action_spec`` (6 OSC deltas + 1 gripper),
  drawn in advance from a seeded RNG, so the timed loop is ``env.step`` alone.
* Warm-up before timing: at least ``--warmup-steps`` steps and
  ``--warmup-seconds`` of wall time per env. The first env step JIT-compiles
  robosuite's numba kernels; they are cached under ``$NUMBA_CACHE_DIR``, which
  defaults to ``<venv>/numba-cache`` here.
* Each measurement: R repeats of about S wall seconds. The median and every run
  are reported. ``physics_steps_per_env_step`` is measured (simulated-time delta /
  (env steps x model timestep)), not taken from the config.
* Single thread, as in ``physics_mujoco.py``: the BLAS/OpenMP thread env vars are
  set to 1 before numpy is loaded, and the process is pinned to one CPU.

robosuite quirks handled in-process, so no file in site-packages is edited:
* Importing robosuite without a ``robosuite/macros_private.py`` logs
  "No private macro file found!" (and its fix is to write that file into
  site-packages). This script puts an in-memory ``robosuite.macros_private``
  module into ``sys.modules`` before the import instead. It sets the console log
  level (ERROR, or INFO with ``--verbose``), so the expected warnings about the
  missing optional ``robosuite_models`` and ``mink`` packages are hidden. It
  also sets ``MUJOCO_GPU_RENDERING=False``, so robosuite doesn't force
  ``MUJOCO_GL=egl`` (no GL context is ever made here).
* Any stray ``print`` inside robosuite goes to stderr (stdout is redirected
  while the benchmark runs). MuJoCo warnings go to stderr, not stdout and
  ./MUJOCO_LOG.TXT.
"""

import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
           "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"
# numba's on-disk cache for robosuite's JIT kernels: keep it in the venv, out of
# site-packages (numba falls back to site-packages/__pycache__ otherwise)
os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(sys.prefix, "numba-cache"))

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import types  # noqa: E402

import numpy as np  # noqa: E402

# (key, robosuite env, robot, control_freq)
STEP_CASES = (
    ("lift_panda_osc_20hz", "Lift", "Panda", 20),
    ("lift_ur5e_osc_500hz", "Lift", "UR5e", 500),
)
RESET_KEY = "lift_reset_ms"
RESET_CASE = STEP_CASES[0]  # reset cost is measured on the env of (a)
MIN_RESETS_PER_RUN = 3
ACTION_BANK = 4096  # pre-drawn random actions, cycled


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def install_private_macros(console_level):
    """Stand in for robosuite/macros_private.py, which robosuite.macros star-imports
    if present, so nothing has to be written into site-packages."""
    mod = types.ModuleType("robosuite.macros_private")
    mod.CONSOLE_LOGGING_LEVEL = console_level
    mod.FILE_LOGGING_LEVEL = None
    mod.MUJOCO_GPU_RENDERING = False
    # robosuite's defaults, spelled out because the timings depend on them
    mod.SIMULATION_TIMESTEP = 0.002
    mod.ENABLE_NUMBA = True
    mod.CACHE_NUMBA = True
    sys.modules[mod.__name__] = mod


def pin_cpu(cpu):
    try:
        cpus = sorted(os.sched_getaffinity(0))
        cpu = cpu if cpu is not None else cpus[-1]
        os.sched_setaffinity(0, {cpu})
        log(f"pinned to CPU {cpu} (of {len(cpus)} allowed; "
            f"os.cpu_count()={os.cpu_count()}, loadavg={os.getloadavg()})")
        return cpu
    except (AttributeError, OSError) as e:
        log(f"could not pin CPU: {e}")
        return None


def summary(runs, ndigits, **extra):
    return {"median": round(statistics.median(runs), ndigits),
            "runs": [round(r, ndigits) for r in runs], **extra}


class Bench:
    def __init__(self, suite, args):
        self.suite = suite
        self.args = args
        self.warmed_up = False

    def make_env(self, env_name, robot, control_freq):
        suite = self.suite
        cfg = suite.load_composite_controller_config(controller="BASIC")
        t0 = time.perf_counter()
        env = suite.make(
            env_name,
            robots=robot,
            controller_configs=cfg,
            has_renderer=False,
            has_offscreen_renderer=False,
            use_camera_obs=False,
            control_freq=control_freq,
            ignore_done=True,
            hard_reset=self.args.hard_reset,
            seed=self.args.seed,
        )
        for r in env.robots:
            for arm in r.arms:
                name = r.part_controllers[arm].name
                if name != "OSC_POSE":
                    raise RuntimeError(f"{robot} arm {arm!r}: controller {name}, expected OSC_POSE")
        log(f"  made {env_name}/{robot} @ {control_freq} Hz in {time.perf_counter() - t0:.2f} s; "
            f"controllers {[self.describe_controllers(r) for r in env.robots]}, "
            f"action dim {env.action_dim}, model dt {env.model_timestep}, "
            f"control dt {env.control_timestep:.6g}")
        return env

    @staticmethod
    def describe_controllers(robot):
        """{part: controller}: the controller type for arms, the class for the rest
        (robosuite's gripper controller reports its base class's name)."""
        return {k: v.name if k in robot.arms else type(v).__name__
                for k, v in robot.part_controllers.items()}

    def actions(self, env):
        lo, hi = env.action_spec
        rng = np.random.default_rng(self.args.seed)
        return rng.uniform(lo, hi, size=(ACTION_BANK, env.action_dim))

    def warm_up(self, env, actions):
        """At least --warmup-steps env steps and --warmup-seconds of wall time."""
        env.reset()
        t0 = time.perf_counter()
        n = 0
        while n < self.args.warmup_steps or time.perf_counter() - t0 < self.args.warmup_seconds:
            env.step(actions[n % ACTION_BANK])
            n += 1
        note = "" if self.warmed_up else " (the first warm-up also loads/JIT-compiles robosuite's numba kernels)"
        self.warmed_up = True
        log(f"  warm-up: {n} steps in {time.perf_counter() - t0:.2f} s{note}")

    def time_steps(self, env, actions):
        """One timed run: env-steps/s over ~--seconds, plus physics steps per env step."""
        env.reset()
        for i in range(10):  # untimed: the first steps after a (hard) reset
            env.step(actions[i])
        seconds = self.args.seconds
        sim_t0 = env.sim.data.time
        n = 0
        t0 = time.perf_counter()
        deadline = t0 + seconds
        while True:
            env.step(actions[n % ACTION_BANK])
            n += 1
            now = time.perf_counter()
            if now >= deadline:
                break
        wall = now - t0
        substeps = (env.sim.data.time - sim_t0) / (n * env.sim.model.opt.timestep)
        return n / wall, n, substeps

    def bench_steps(self, key, env_name, robot, control_freq):
        log(f"{key}: {env_name}, robot {robot}, OSC_POSE, control_freq {control_freq}")
        env = self.make_env(env_name, robot, control_freq)
        try:
            actions = self.actions(env)
            self.warm_up(env, actions)
            rates, counts, substeps = [], [], []
            for i in range(self.args.repeats):
                rate, n, sub = self.time_steps(env, actions)
                rates.append(rate)
                counts.append(n)
                substeps.append(sub)
                log(f"  run {i + 1}/{self.args.repeats}: {rate:.1f} env-steps/s "
                    f"({n} steps, {sub:.3f} physics steps/env step)")
        finally:
            env.close()
        return summary(rates, 1, unit="env-steps/s", steps=counts), round(statistics.median(substeps), 3)

    def bench_reset(self, env_name, robot, control_freq):
        log(f"{RESET_KEY}: env.reset() of {env_name}/{robot} @ {control_freq} Hz, "
            f"hard_reset={self.args.hard_reset}")
        env = self.make_env(env_name, robot, control_freq)
        try:
            actions = self.actions(env)
            self.warm_up(env, actions)
            env.reset()  # untimed: first reset after the warm-up
            medians, counts = [], []
            for i in range(self.args.repeats):
                ms = []
                t_end = time.perf_counter() + self.args.seconds
                while len(ms) < MIN_RESETS_PER_RUN or time.perf_counter() < t_end:
                    env.step(actions[len(ms) % ACTION_BANK])  # untimed
                    t0 = time.perf_counter()
                    env.reset()
                    ms.append((time.perf_counter() - t0) * 1e3)
                medians.append(statistics.median(ms))
                counts.append(len(ms))
                log(f"  run {i + 1}/{self.args.repeats}: median {medians[-1]:.2f} ms over {len(ms)} resets "
                    f"(min {min(ms):.2f}, max {max(ms):.2f})")
        finally:
            env.close()
        return summary(medians, 2, unit="ms (per run: median env.reset())", resets=counts,
                       hard_reset=self.args.hard_reset)


def main():
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="Measurements: " + ", ".join(k for k, *_ in STEP_CASES) + f", {RESET_KEY}. "
               "Prints one JSON object on stdout; diagnostics go to stderr.")
    ap.add_argument("--seconds", type=float, default=3.0, help="wall seconds per timed run (default 3)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per measurement (default 3)")
    ap.add_argument("--warmup-steps", type=int, default=50,
                    help="minimum untimed env steps per env before timing (default 50)")
    ap.add_argument("--warmup-seconds", type=float, default=1.0,
                    help="minimum untimed wall seconds per env before timing (default 1)")
    ap.add_argument("--hard-reset", action=argparse.BooleanOptionalAction, default=True,
                    help="robosuite's hard_reset (rebuild model + sim on reset; robosuite's default: on)")
    ap.add_argument("--only", default=None,
                    help="comma-separated subset of the measurement keys (default: all)")
    ap.add_argument("--seed", type=int, default=0, help="env + action RNG seed (default 0)")
    ap.add_argument("--cpu", type=int, default=None, help="pin to this CPU (default: last allowed)")
    ap.add_argument("--verbose", action="store_true", help="show robosuite's INFO/WARNING log lines")
    args = ap.parse_args()
    if args.seconds <= 0 or args.repeats < 1:
        ap.error("--seconds must be > 0 and --repeats >= 1")
    keys = [k for k, *_ in STEP_CASES] + [RESET_KEY]
    only = keys if args.only is None else [k.strip() for k in args.only.split(",") if k.strip()]
    unknown = sorted(set(only) - set(keys))
    if unknown:
        ap.error(f"unknown --only key(s) {unknown}; choose from {keys}")

    json_out = sys.stdout
    with contextlib.redirect_stdout(sys.stderr):
        cpu = pin_cpu(args.cpu)
        install_private_macros("INFO" if args.verbose else "ERROR")
        t_import = time.perf_counter()
        import mujoco
        import robosuite as suite
        log(f"imported robosuite {suite.__version__} (mujoco {mujoco.__version__}, numpy {np.__version__}) "
            f"in {time.perf_counter() - t_import:.2f} s")
        # MuJoCo's default warning handler prints to stdout and appends to ./MUJOCO_LOG.TXT
        mujoco.set_mju_user_warning(lambda msg: log(f"MuJoCo WARNING: {msg}"))
        try:
            import numba
            numba_version = numba.__version__
        except ImportError:
            numba_version = None

        out = {
            "robosuite_version": suite.__version__,
            "mujoco_version": mujoco.__version__,
            "numpy_version": np.__version__,
            "numba_version": numba_version,
            "config": {
                "seconds": args.seconds, "repeats": args.repeats,
                "warmup_steps": args.warmup_steps, "warmup_seconds": args.warmup_seconds,
                "controller": 'load_composite_controller_config(controller="BASIC") -> arm OSC_POSE',
                "has_renderer": False, "has_offscreen_renderer": False, "use_camera_obs": False,
                "use_object_obs": True, "ignore_done": True, "hard_reset": args.hard_reset,
                "actions": "uniform random in env.action_spec", "seed": args.seed,
                "threads": 1, "cpu": cpu,
            },
        }
        bench = Bench(suite, args)
        substeps = {}
        t0 = time.perf_counter()
        for key, env_name, robot, hz in STEP_CASES:
            if key in only:
                out[key], substeps[key] = bench.bench_steps(key, env_name, robot, hz)
        if RESET_KEY in only:
            out[RESET_KEY] = bench.bench_reset(*RESET_CASE[1:])
        out["physics_steps_per_env_step"] = substeps
        out["total_wall_s"] = round(time.perf_counter() - t0, 2)
    print(json.dumps(out, indent=1), file=json_out, flush=True)


if __name__ == "__main__":
    main()
