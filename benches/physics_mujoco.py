#!/usr/bin/env python3
"""MuJoCo side of echogym's side-by-side physics benchmark.

Usage (from the repo root; create the venv first with ``benches/peers-venv``)::

    benches/.venv-peers/bin/python benches/physics_mujoco.py \\
        benches/scenes/sample_scene.json --seconds 3 --repeats 3 \\
        [--particles-scale K] [--scene-only a|b|c|ab|...] [--torso-support table|pinned]

Prints ONE JSON object on stdout; every progress / diagnostic line goes to stderr.

Scenes (all built as MJCF strings and loaded with ``mujoco.MjModel.from_xml_string``;
option timestep and gravity from the scene, integrator ``implicitfast``):

(a) ``torso_alone`` -- the soft torso only: a 3-D ``<flexcomp type="grid" dim="3">``
    box (full-DOF flex: every vertex is a body with 3 slide DOFs; no ``dof="trilinear"``
    reduction) with the scene's grid counts (or, with ``--particles-scale``, a grid
    whose vertex count is about K x the scene's particle count), vertex mass =
    ``particle_mass`` (scaled grids keep the total torso mass), linear-elastic FEM
    (``<edge equality="false"/>`` + ``<elasticity young poisson damping>``), resting on
    the table, gravity on. The timed window starts from the undeformed box, so it
    covers settling and then resting.
(b) ``arm_alone`` -- the serial arm from ``scene.robot`` (URDF-style joint origins,
    fixed-axis RPY, hinge joints with ranges and damping, full inertias, capsule
    geoms), the probe box at the flange, one position actuator (kp/kv) per joint
    holding ``home``; starts at home. No torso, no table.
(c) ``arm_press_slide`` -- arm + probe + torso + table. Before timing, the torso is
    settled under gravity with the arm parked above it, the settled top surface is
    measured, and a joint-space trajectory for the probe tip (hover 2 cm above the
    torso centre, press to ``depth`` below the settled surface, slide +travel, -travel,
    back to centre along the torso's y axis at ``speed``, lift) is solved by damped
    least squares IK with ``mj_jacSite`` on a scratch MjData of the arm model. The
    timed loop only copies the precomputed targets into ``data.ctrl`` and calls
    ``mj_step`` (looping the trajectory if needed). The mean probe contact force is
    obtained by replaying the last timed run step-for-step (MuJoCo is deterministic)
    outside the timer, so measuring it costs the timed loop nothing.

Timing / fairness choices:
* One core: BLAS/OpenMP thread env vars are set to 1 before numpy/mujoco load, the
  process is pinned to a single CPU (``sched_setaffinity``), and no MuJoCo thread
  pool is created (``mj_step`` is single-threaded without one).
* Each scene: R repeats, each restores the same initial state, warms up briefly
  (untimed), then runs ``mj_step`` for about ``--seconds`` of wall time; the median
  steps/s is reported (all runs are listed too). All three scenes use the same Python
  loop (copy a ctrl row, call ``mj_step``), so the per-step Python overhead (~1 us) is
  the same for all.
* Arm bodies use ``gravcomp="1"`` (gravity compensation as a passive force) so that
  moderate gains (default kp 400, kv 20) hold the pose; arm link capsules are visual
  only (contype/conaffinity 0) -- only the probe collides (with torso and table).
* Table: MuJoCo caps the contacts between one body and one flex at 50
  (``mjMAXCONPAIR``, ``filterFlexContacts`` in 3.9.0), and every world geom shares the
  world body, so a single table box lets the torso sink through. The table's
  collision surface under the torso is therefore split into static tile bodies (one
  per ~3x3 torso cells); the big table box itself is visual only.

What is / isn't comparable to echogym's rapier particle torso:
* rapier's torso is a shell of particles, each tied by a spring (k_p = m_p * stiffness,
  c_p = m_p * damping) to its rest position (a Winkler foundation), plus neighbour
  springs and a volume pressure; it has no contacts with the table. MuJoCo's flex is a
  volumetric tetrahedral FEM solid (interior vertices included) resting on the table
  through contacts. The Winkler modulus kappa = density * height * stiffness is mapped
  to a Young's modulus E = kappa * height (an elastic layer of thickness h has
  kappa ~ E / h); the seed's damping becomes Rayleigh damping b/k (0.0133 s), clamped
  to 0.0004 s * (h_min / 20 mm)^2 (~0.0006 s for the sample grid) because 3.9.0's
  explicit flex damping blows up at 2 ms above roughly that (``--flex-damping``
  overrides). The timed window therefore sees a less damped, more oscillatory body.
* Vertex counts match (about) the particle count, but MuJoCo's cost is dominated by
  the FEM passive forces of ~4x as many tetrahedra and, with ``--torso-support
  table``, by hundreds of torso-table contacts in the constraint solver;
  ``--torso-support pinned`` pins the bottom vertex layer instead (no table
  contacts), which is closer to rapier's anchored particles. Measured on the sample
  scene (2-core VM): table support ~5-10 steps/s with the default Newton solver
  (~2300 contact rows on ~2300 DOFs), ~90 steps/s with ``--solver CG`` (which then
  runs at its 100-iteration cap), ~600-900 steps/s pinned.
* Probe contact: MuJoCo soft contacts (solref/solimp defaults) on flex elements
  inflated by ``particle_radius``; rapier uses its own contact model, so forces are a
  sanity check only, not a like-for-like comparison.
"""

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
           "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import mujoco  # noqa: E402


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def f(x):
    return " ".join("%.9g" % float(v) for v in np.ravel(x))


def rpy_quat(rpy):
    """URDF fixed-axis RPY, R = Rz(yaw) Ry(pitch) Rx(roll), as a MuJoCo quat (w x y z)."""
    r, p, y = rpy
    cr, sr = math.cos(r / 2), math.sin(r / 2)
    cp, sp = math.cos(p / 2), math.sin(p / 2)
    cy, sy = math.cos(y / 2), math.sin(y / 2)
    return [cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr]


# --------------------------------------------------------------------------- torso

def torso_grid(torso, scale):
    """Vertex counts per axis: the scene's grid at scale 1, else a near-isotropic grid
    whose product is as close as possible to scale * particle_count."""
    size = np.asarray(torso["size"], float)
    target = float(torso["particle_count"]) * scale
    grid = torso.get("grid")
    if grid and scale == 1.0:
        return [int(n) for n in grid]
    # spacing h with prod(size/h + 1) = target (bisection), then a local search
    lo, hi = 1e-4, float(size.max())
    for _ in range(100):
        h = 0.5 * (lo + hi)
        if np.prod(size / h + 1) > target:
            lo = h
        else:
            hi = h
    base = size / h + 1
    best = None
    rng = [range(max(2, int(b) - 2), int(b) + 4) for b in base]
    for nx in rng[0]:
        for ny in rng[1]:
            for nz in rng[2]:
                sp = size / (np.array([nx, ny, nz]) - 1)
                aniso = sp.max() / sp.min()
                cost = abs(nx * ny * nz - target) / target + 0.05 * (aniso - 1)
                if best is None or cost < best[0]:
                    best = (cost, [nx, ny, nz])
    return best[1]


def torso_params(scene, args):
    t = scene["torso"]
    size = np.asarray(t["size"], float)
    grid = torso_grid(t, args.particles_scale)
    nvert = int(np.prod(grid))
    total_mass = float(t["particle_mass"]) * float(t["particle_count"])
    if args.particles_scale == 1.0:
        vmass = float(t["particle_mass"])
    else:
        vmass = total_mass / nvert  # keep the physical torso's mass when rescaling
    density = vmass * nvert / float(np.prod(size))
    young = args.young if args.young else density * size[2] ** 2 * float(t["stiffness"])
    seed_beta = float(t["damping"]) / float(t["stiffness"])
    # 3.9.0 applies flex Rayleigh damping explicitly: stable only below ~c * h^2
    # (0.001 s blows up at h = 21 mm, 0.0003 s is fine), so clamp the seed's b/k
    h_min = float(np.min((size - 2 * float(t["particle_radius"])) / (np.array(grid) - 1)))
    beta_max = 0.0004 * (h_min / 0.02) ** 2
    beta = args.flex_damping if args.flex_damping is not None else min(seed_beta, beta_max)
    return dict(size=size, grid=grid, nvert=nvert, vmass=vmass, young=young,
                beta=beta, seed_beta=seed_beta, radius=float(t["particle_radius"]),
                center=[t["center_xy"][0], t["center_xy"][1], float(t["bottom_z"]) + size[2] / 2])


def torso_xml(tp, args):
    # vertices span size - 2*radius so that the collision surface (elements inflated by
    # the radius) is the scene's box, bottom exactly on the table top
    spacing = (tp["size"] - 2 * tp["radius"]) / (np.array(tp["grid"]) - 1)
    pin = ""
    if args.torso_support == "pinned":
        nx, ny, _ = tp["grid"]
        pin = f'<pin gridrange="0 0 0 {nx - 1} {ny - 1} 0"/>'
    return f"""
  <flexcomp name="torso" type="grid" dim="3" count="{f(tp['grid'])}" spacing="{f(spacing)}"
            pos="{f(tp['center'])}" radius="{tp['radius']:.9g}" mass="{tp['vmass'] * tp['nvert']:.9g}"
            rgba="0.9 0.7 0.6 1">
   <edge equality="false"/>
   <elasticity young="{tp['young']:.9g}" poisson="{args.poisson:.9g}" damping="{tp['beta']:.9g}"/>
   <contact selfcollide="none" internal="false" contype="1" conaffinity="1" friction="{args.friction:.9g}"/>
   {pin}
  </flexcomp>"""


def table_xml(scene, tp, args, with_tiles):
    tb = scene["table"]
    c = np.asarray(tb["center"], float)
    he = np.asarray(tb["half_extents"], float)
    top = c[2] + he[2]
    out = [f'  <geom name="table" type="box" pos="{f(c)}" size="{f(he)}" '
           f'contype="0" conaffinity="0" rgba="0.5 0.45 0.4 1"/>']
    if with_tiles and args.torso_support == "table":
        # collision tiles: static bodies covering the torso footprint + one cell margin
        spacing = tp["size"] / (np.array(tp["grid"]) - 1)
        cx, cy = tp["center"][0], tp["center"][1]
        ext = tp["size"][:2] / 2 + spacing[:2] * 1.5
        ntile = [max(1, math.ceil(2 * ext[i] / (3 * spacing[i]))) for i in range(2)]
        tsz = 2 * ext / np.array(ntile)
        th = 0.01
        for i in range(ntile[0]):
            for j in range(ntile[1]):
                x = cx - ext[0] + (i + 0.5) * tsz[0]
                y = cy - ext[1] + (j + 0.5) * tsz[1]
                out.append(f'  <body name="tile_{i}_{j}" pos="{x:.9g} {y:.9g} {top - th:.9g}">'
                           f'<geom type="box" size="{tsz[0] / 2:.9g} {tsz[1] / 2:.9g} {th}" '
                           f'contype="1" conaffinity="1" friction="{args.friction:.9g}" '
                           f'rgba="0.5 0.45 0.4 0.3"/></body>')
    return "\n".join(out), top


# --------------------------------------------------------------------------- arm

def arm_xml(scene, args):
    rb, pr = scene["robot"], scene["probe"]
    lines = [f'  <body name="base" pos="{f(rb["base_pos"])}" quat="{f(rpy_quat(rb["base_rpy"]))}">']
    depth = 1
    for jt in rb["joints"]:
        ln = jt["link"]
        ind = "  " * (depth + 1)
        lines.append(f'{ind}<body name="{ln["name"]}" pos="{f(jt["origin_xyz"])}" '
                     f'quat="{f(rpy_quat(jt["origin_rpy"]))}" gravcomp="1">')
        lines.append(f'{ind}  <joint name="{jt["name"]}" type="hinge" axis="{f(jt["axis"])}" '
                     f'limited="true" range="{jt["lower"]:.9g} {jt["upper"]:.9g}" '
                     f'damping="{jt.get("damping", 0.0):.9g}" armature="{args.armature:.9g}"/>')
        lines.append(f'{ind}  <inertial pos="{f(ln["com"])}" mass="{ln["mass"]:.9g}" '
                     f'fullinertia="{f(ln["inertia"])}"/>')
        for cap in ln.get("capsules", []):
            lines.append(f'{ind}  <geom type="capsule" fromto="{f(cap["a"])} {f(cap["b"])}" '
                         f'size="{cap["radius"]:.9g}" contype="0" conaffinity="0" mass="0" '
                         f'rgba="0.85 0.85 0.9 1"/>')
        depth += 1
    ind = "  " * (depth + 1)
    he = np.asarray(pr["half_extents"], float)
    tip = float(pr["tip_offset"])
    lines.append(f'{ind}<body name="flange" pos="{f(rb["flange_xyz"])}" '
                 f'quat="{f(rpy_quat(rb["flange_rpy"]))}" gravcomp="1">')
    lines.append(f'{ind}  <geom name="probe" type="box" size="{f(he)}" pos="0 0 {tip - he[2]:.9g}" '
                 f'mass="{pr["mass"]:.9g}" contype="1" conaffinity="1" '
                 f'friction="{args.friction:.9g}" rgba="0.2 0.3 0.8 1"/>')
    lines.append(f'{ind}  <site name="tip" pos="0 0 {tip:.9g}" size="0.003"/>')
    lines.append(f'{ind}</body>')
    for d in range(depth, 0, -1):
        lines.append("  " * d + "</body>")
    acts = "\n".join(
        f'  <position name="act_{jt["name"]}" joint="{jt["name"]}" kp="{args.kp:.9g}" kv="{args.kv:.9g}"/>'
        for jt in rb["joints"])
    return "\n".join(lines), acts


def model_xml(scene, args, torso, arm):
    dt = float(scene["dt"])
    g = scene.get("gravity", [0, 0, -9.81])
    body, acts, tp = [], "", None
    if torso:
        tp = torso_params(scene, args)
    tab, _ = table_xml(scene, tp, args, with_tiles=torso) if torso else ("", None)
    if tab:
        body.append(tab)
    if torso:
        body.append(torso_xml(tp, args))
    if arm:
        a, acts = arm_xml(scene, args)
        body.append(a)
    return f"""<mujoco model="echogym_bench">
 <compiler angle="radian" autolimits="true" balanceinertia="true"/>
 <option timestep="{dt:.9g}" gravity="{f(g)}" integrator="implicitfast" solver="{args.solver}"/>
 <size memory="{args.memory}"/>
 <worldbody>
  <light pos="0 0 3" dir="0 0 -1"/>
{chr(10).join(body)}
 </worldbody>
 <actuator>
{acts}
 </actuator>
</mujoco>""", tp


# --------------------------------------------------------------------------- IK

def arm_qadr(m, scene):
    names = [j["name"] for j in scene["robot"]["joints"]]
    qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in names])
    dadr = np.array([m.jnt_dofadr[m.joint(n).id] for n in names])
    return qadr, dadr


def ik_path(m, d, site, targets, R_t, q0, q_null, lo, hi, lam=1e-3, null_gain=0.05):
    """DLS IK (position + orientation) along a list of tip targets, warm-started."""
    nv = m.nv
    jacp = np.zeros((3, nv))
    jacr = np.zeros((3, nv))
    q = q0.copy()
    out = np.zeros((len(targets), len(q0)))
    worst = 0.0
    for k, p_t in enumerate(targets):
        for _ in range(200):
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            p = d.site_xpos[site]
            R = d.site_xmat[site].reshape(3, 3)
            ep = p_t - p
            er = 0.5 * sum(np.cross(R[:, i], R_t[:, i]) for i in range(3))
            e = np.concatenate([ep, er])
            if np.linalg.norm(ep) < 1e-6 and np.linalg.norm(er) < 1e-5:
                break
            mujoco.mj_jacSite(m, d, jacp, jacr, site)
            J = np.vstack([jacp, jacr])
            JJt = J @ J.T + lam ** 2 * np.eye(6)
            dq = J.T @ np.linalg.solve(JJt, e)
            N = np.eye(nv) - J.T @ np.linalg.solve(JJt, J)
            dq += N @ (null_gain * (q_null - q))
            q = np.clip(q + dq, lo, hi)
        worst = max(worst, float(np.linalg.norm(ep)))
        out[k] = q
    return out, worst


def tip_path(scene, top_z, dt):
    ps = scene["press_slide"]
    c = np.array([scene["torso"]["center_xy"][0], scene["torso"]["center_xy"][1]])
    v, depth, travel = float(ps["speed"]), float(ps["depth"]), float(ps["travel"])
    hover = top_z + 0.02
    press = top_z - depth
    way = [(c[0], c[1], hover), (c[0], c[1], hover), (c[0], c[1], press),
           (c[0], c[1] + travel, press), (c[0], c[1] - travel, press),
           (c[0], c[1], press), (c[0], c[1], hover)]
    pts, phase = [np.array(way[0])], [0]
    for i in range(1, len(way)):
        a, b = np.array(way[i - 1]), np.array(way[i])
        n = max(1, int(round((np.linalg.norm(b - a) / v if i > 1 else 0.2) / dt)))
        pressing = 1 if 3 <= i <= 5 else 0
        for s in range(1, n + 1):
            pts.append(a + (b - a) * s / n)
            phase.append(pressing)
    return np.array(pts), np.array(phase)


# --------------------------------------------------------------------------- timing

def timed_runs(m, d, init_state, ctrl_rows, seconds, repeats, warm_s):
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    L = len(ctrl_rows)
    nu = m.nu
    rates, last = [], None
    for r in range(repeats):
        mujoco.mj_setState(m, d, init_state, spec)
        mujoco.mj_forward(m, d)
        i = 0
        # warm-up (untimed)
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < warm_s or i < 10:
            if nu:
                d.ctrl[:] = ctrl_rows[i % L]
            mujoco.mj_step(m, d)
            i += 1
        per_step = (time.perf_counter() - t0) / i
        chunk = max(1, int(0.01 / per_step))
        warm_steps = i
        n = 0
        t0 = time.perf_counter()
        while True:
            for _ in range(chunk):
                if nu:
                    d.ctrl[:] = ctrl_rows[i % L]
                mujoco.mj_step(m, d)
                i += 1
            n += chunk
            el = time.perf_counter() - t0
            if el >= seconds:
                break
        rates.append(n / el)
        last = (warm_steps, n)
        bad = d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number
        log(f"    run {r + 1}/{repeats}: {n} steps in {el:.2f} s -> {n / el:.1f} steps/s"
            f" (ncon {d.ncon}{', UNSTABLE' if bad else ''})")
    return rates, last


def probe_force_replay(m, d, init_state, ctrl_rows, phase, warm_steps, n):
    """Replay warm-up + timed steps exactly, measuring the net probe contact force."""
    mujoco.mj_setState(m, d, init_state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(m, d)
    probe = m.geom("probe").id
    L = len(ctrl_rows)
    f6 = np.zeros(6)
    forces, pressing = [], []
    for i in range(warm_steps + n):
        d.ctrl[:] = ctrl_rows[i % L]
        mujoco.mj_step(m, d)
        if i < warm_steps:
            continue
        tot = np.zeros(3)
        for c in range(d.ncon):
            con = d.contact[c]
            if con.geom[0] == probe or con.geom[1] == probe:
                mujoco.mj_contactForce(m, d, c, f6)
                tot += con.frame.reshape(3, 3).T @ f6[:3]
        forces.append(np.linalg.norm(tot))
        pressing.append(phase[i % L])
    forces, pressing = np.array(forces), np.array(pressing, bool)
    return (float(forces.mean()),
            float(forces[pressing].mean()) if pressing.any() else 0.0,
            float(forces.max()))


def counts(m):
    return {"bodies": int(m.nbody - 1), "dofs": int(m.nv), "vertices": int(m.nflexvert),
            "tetrahedra": int(m.nflexelem), "actuators": int(m.nu)}


def bench_scene(key, scene, args):
    dt = float(scene["dt"])
    torso, arm = key in ("a", "c"), key in ("b", "c")
    xml, tp = model_xml(scene, args, torso, arm)
    if args.dump_xml:
        with open(f"{args.dump_xml}_{key}.xml", "w") as fh:
            fh.write(xml)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    res = counts(m)
    if tp:
        res.update(grid=tp["grid"], vertex_mass_kg=tp["vmass"], young_pa=tp["young"],
                   poisson=args.poisson, rayleigh_damping_s=tp["beta"],
                   flex_dof="full", torso_support=args.torso_support)
        if args.particles_scale == 1.0 and tp["nvert"] != scene["torso"]["particle_count"]:
            log(f"  note: grid {tp['grid']} gives {tp['nvert']} vertices, scene particle_count "
                f"{scene['torso']['particle_count']}")
    phase = np.zeros(1, int)
    ctrl_rows = np.zeros((1, m.nu))
    if arm:
        qadr, _ = arm_qadr(m, scene)
        home = np.asarray(scene["robot"]["home"], float)
        d.qpos[qadr] = home
        ctrl_rows = home[None, :]
        d.ctrl[:] = home
    mujoco.mj_forward(m, d)
    t_pre = time.perf_counter()
    if key == "c":
        ctrl_rows, phase, extra = prepare_press_slide(m, d, scene, args, tp, dt)
        res.update(extra)
    res["precompute_s"] = round(time.perf_counter() - t_pre, 3)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    init = np.zeros(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, init, spec)
    log(f"  {key}: nbody {m.nbody} nv {m.nv} nflexvert {m.nflexvert} nflexelem {m.nflexelem} nu {m.nu}")
    rates, (warm_steps, n) = timed_runs(m, d, init, ctrl_rows, args.seconds, args.repeats,
                                        min(0.5, 0.1 * args.seconds))
    res["steps_per_s"] = statistics.median(rates)
    res["steps_per_s_runs"] = [round(r, 2) for r in rates]
    res["realtime_factor"] = res["steps_per_s"] * dt
    res["sim_time_end_s"] = float(d.time)
    res["unstable"] = bool(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number)
    if key == "c":
        mean_f, mean_press, max_f = probe_force_replay(m, d, init, ctrl_rows, phase, warm_steps, n)
        res["mean_probe_force_n"] = mean_f
        res["mean_probe_force_pressing_n"] = mean_press
        res["max_probe_force_n"] = max_f
        log(f"  c: mean probe force over timed run {mean_f:.2f} N "
            f"(while pressed {mean_press:.2f} N, max {max_f:.2f} N)")
    return res


def prepare_press_slide(m, d, scene, args, tp, dt):
    """Settle the torso with the arm parked, measure the top, solve the IK trajectory,
    move the arm to the hover pose; leaves d in the state the timed runs start from."""
    qadr, _ = arm_qadr(m, scene)
    home = np.asarray(scene["robot"]["home"], float)
    # 1. settle torso under gravity, arm held at home
    for _ in range(int(round(args.settle / dt))):
        mujoco.mj_step(m, d)
    cx, cy = scene["torso"]["center_xy"]
    v = d.flexvert_xpos
    top_layer = v[:, 2] > np.median(v[:, 2])
    near = np.argsort(np.hypot(v[:, 0] - cx, v[:, 1] - cy) + 10 * (~top_layer))[:4]
    top_z = float(v[near, 2].max()) + tp["radius"]
    undeformed_top = float(scene["torso"]["bottom_z"]) + tp["size"][2]
    log(f"  c: settled torso top {top_z:.4f} m (undeformed {undeformed_top:.4f} m)")
    # 2. IK on the arm-only model, scratch data
    xml_b, _ = model_xml(scene, args, torso=False, arm=True)
    mb = mujoco.MjModel.from_xml_string(xml_b)
    db = mujoco.MjData(mb)
    qb, _ = arm_qadr(mb, scene)
    assert np.all(qb == np.arange(len(qb))), "arm model should hold only the arm joints"
    site = mb.site("tip").id
    lo = mb.jnt_range[:, 0].copy()
    hi = mb.jnt_range[:, 1].copy()
    db.qpos[:] = home
    mujoco.mj_kinematics(mb, db)
    Rh = db.site_xmat[site].reshape(3, 3)
    z_t = np.array([0.0, 0.0, -1.0])
    x_t = Rh[:, 0] - (Rh[:, 0] @ z_t) * z_t
    x_t /= np.linalg.norm(x_t)
    R_t = np.column_stack([x_t, np.cross(z_t, x_t), z_t])
    pts, phase = tip_path(scene, top_z, dt)
    qpath, worst = ik_path(mb, db, site, pts, R_t, home, home, lo, hi)
    log(f"  c: IK path {len(pts)} points ({len(pts) * dt:.2f} s sim), worst tip error {worst * 1e3:.3f} mm")
    # 3. move the arm from home to the hover pose (ramp), hold, so timing starts settled
    nramp = int(round(1.0 / dt))
    for k in range(nramp + int(round(0.3 / dt))):
        s = min(1.0, k / nramp)
        s = s * s * (3 - 2 * s)
        d.ctrl[:] = home + (qpath[0] - home) * s
        mujoco.mj_step(m, d)
    tip = d.site_xpos[m.site("tip").id]
    log(f"  c: at hover, tip {np.round(tip, 4).tolist()} target {np.round(pts[0], 4).tolist()}")
    return qpath, phase, {"settled_top_z": top_z, "trajectory_steps": int(len(pts)),
                          "ik_worst_tip_error_m": worst}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--seconds", type=float, default=3.0, help="timed wall seconds per run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--particles-scale", type=float, default=1.0)
    ap.add_argument("--scene-only", default="abc", help="subset of a,b,c (e.g. 'a', 'bc')")
    ap.add_argument("--torso-support", choices=["table", "pinned"], default="table")
    ap.add_argument("--solver", choices=["Newton", "CG", "PGS"], default="Newton")
    ap.add_argument("--kp", type=float, default=400.0)
    ap.add_argument("--kv", type=float, default=20.0)
    ap.add_argument("--armature", type=float, default=0.0)
    ap.add_argument("--poisson", type=float, default=0.3)
    ap.add_argument("--young", type=float, default=None, help="override derived Young's modulus [Pa]")
    ap.add_argument("--flex-damping", type=float, default=None, help="Rayleigh damping [s]")
    ap.add_argument("--friction", type=float, default=0.1)
    ap.add_argument("--settle", type=float, default=1.0, help="sim seconds to settle torso (scene c)")
    ap.add_argument("--memory", default="256M", help="MJCF <size memory>")
    ap.add_argument("--cpu", type=int, default=None, help="pin to this CPU (default: first allowed)")
    ap.add_argument("--dump-xml", default=None, help="write generated MJCF to PREFIX_<scene>.xml")
    args = ap.parse_args()

    try:
        cpus = sorted(os.sched_getaffinity(0))
        cpu = args.cpu if args.cpu is not None else cpus[-1]
        os.sched_setaffinity(0, {cpu})
        log(f"pinned to CPU {cpu}")
    except (AttributeError, OSError) as e:
        log(f"could not pin CPU: {e}")

    # MuJoCo's default warning handler prints to stdout and appends to MUJOCO_LOG.TXT in
    # the cwd: route warnings to stderr instead (stdout carries only the JSON)
    mujoco.set_mju_user_warning(lambda msg: log(f"MuJoCo WARNING: {msg}"))

    with open(args.scene) as fh:
        scene = json.load(fh)
    names = {"a": "torso_alone", "b": "arm_alone", "c": "arm_press_slide"}
    out = {"mujoco_version": mujoco.__version__, "numpy_version": np.__version__,
           "config": {"seconds": args.seconds, "repeats": args.repeats,
                      "particles_scale": args.particles_scale, "dt": scene["dt"],
                      "integrator": "implicitfast", "solver": args.solver,
                      "torso_support": args.torso_support, "kp": args.kp, "kv": args.kv,
                      "threads": 1, "loop": "python: ctrl row copy + mj_step per step"}}
    t0 = time.perf_counter()
    for key in "abc":
        if key in args.scene_only:
            log(f"scene {key} ({names[key]})")
            out[names[key]] = bench_scene(key, scene, args)
    out["total_wall_s"] = round(time.perf_counter() - t0, 2)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
