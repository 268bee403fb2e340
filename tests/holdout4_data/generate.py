#!/usr/bin/env python3
"""holdout-4: an independent ground-truth generator of force-calibration datasets.

Writes `echogym-recordings/1` datasets that look like a real ultrasound-robotics lab's
session on a human abdomen (position- and force-controlled presses, staircases,
indentation series, palpation chirps, force-controlled sweeps), each with concealed
catalogue effects whose true values go to `truth.json` beside the dataset.

    generate.py --effects sensor_bias,breathing_motion --seed 3 --out DIR
    generate.py --effects none --seed 3 --out DIR
    generate.py --matrix --seeds 1,2 --out DIR
    generate.py --check DIR

Python 3 + numpy only.  See README.md beside this file for every model and range.
"""

import argparse
import itertools
import json
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

GENERATOR = "holdout-4"
CATALOGUE = [
    "sensor_bias", "sensor_delay", "tissue_inertia", "nonlinear_stiffness",
    "viscoelastic_relaxation", "breathing_motion", "site_heterogeneity",
    "sliding_friction", "sensor_filter", "bias_drift", "depth_dependent_damping",
]
# offsets from the torso centre [m] (docs/data.md step 8: the seed's five sites)
SITES = {
    "center": (0.0, 0.0), "upper_left": (-0.06, 0.08), "upper_right": (0.06, 0.08),
    "lower_left": (-0.06, -0.08), "lower_right": (0.06, -0.08),
}
DT = 5e-4          # body integration step [s]
G = 9.81
RATE_RANGE = (50.0, 2000.0)
GAP_FACTOR, GAP_MIN_S, MIN_SAMPLES = 5.0, 0.05, 10
NB = 8             # maximal number of relaxation branches
DU = 2e-5          # elastic table resolution [m]
N_PRE = 25         # table cells below first touch
VIS_TARGET = 3.5   # sigma, generation target
VIS_FAIL = 3.0     # sigma, --check failure threshold


def rng_for(seed, *keys):
    return np.random.default_rng([int(seed)] + [int(k) for k in keys])


def jsonable(x):
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    return x


# ----------------------------------------------------------------------------- geometry

def surface(geom, x, y):
    """True resting skin height and its gradient at world (x, y) (arrays)."""
    cx, cy = geom["center_xy"]
    X, Y = np.asarray(x) - cx, np.asarray(y) - cy
    z = geom["z_center"] + geom["tilt_x"] * X + geom["tilt_y"] * Y \
        - X ** 2 / (2 * geom["Rx"]) - Y ** 2 / (2 * geom["Ry"])
    gx = geom["tilt_x"] - X / geom["Rx"]
    gy = geom["tilt_y"] - Y / geom["Ry"]
    w2 = geom["bump_w"] ** 2
    for site, (sx, sy) in SITES.items():
        a = geom["bumps_m"][site]
        e = a * np.exp(-((X - sx) ** 2 + (Y - sy) ** 2) / (2 * w2))
        z = z + e
        gx = gx - e * (X - sx) / w2
        gy = gy - e * (Y - sy) / w2
    return z, gx, gy


def normal_from_grad(gx, gy):
    n = np.stack([-np.asarray(gx), -np.asarray(gy), np.ones_like(np.asarray(gx, float))], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def quintic(a, b, T, t):
    s = np.clip(t / T, 0.0, 1.0) if T > 0 else np.ones_like(t)
    return a + (b - a) * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)


def waypoints_traj(wps, t):
    """wps: [(t_i, z_i)], quintic between consecutive waypoints, constant outside."""
    z = np.full_like(t, wps[0][1])
    for (t0, z0), (t1, z1) in zip(wps[:-1], wps[1:]):
        m = (t >= t0) & (t <= t1)
        z[m] = quintic(z0, z1, t1 - t0, t[m] - t0)
        z[t > t1] = z1
    return z


def track2(cmd, f_hz, zeta):
    """Robot joint-servo tracking of a commanded coordinate: critically-ish damped 2nd
    order (semi-implicit Euler on the DT grid). Returns position, velocity, acceleration."""
    w = 2 * math.pi * f_hz
    w2, c2 = w * w, 2 * zeta * w
    n = len(cmd)
    x = np.empty(n); v = np.empty(n); a = np.empty(n)
    xi, vi = float(cmd[0]), 0.0
    cl = cmd.tolist()
    for i in range(n):
        ai = w2 * (cl[i] - xi) - c2 * vi
        vi += ai * DT
        xi += vi * DT
        x[i] = xi; v[i] = vi; a[i] = ai
    return x, v, a


def softplus(x, s):
    return s * np.logaddexp(0.0, x / s)


# ----------------------------------------------------------------------------- session

def draw_session(seed):
    """Everything that is not a catalogue effect, from one stream seeded by the seed."""
    r = rng_for(seed, 0)
    S = {"seed": int(seed)}
    cx, cy = r.uniform(0.38, 0.58), r.uniform(-0.12, 0.12)
    geom = {
        "center_xy": [cx, cy], "z_center": r.uniform(0.09, 0.18),
        "Rx": r.uniform(0.35, 0.55), "Ry": r.uniform(0.7, 1.2),
        "tilt_x": r.uniform(-0.02, 0.02), "tilt_y": r.uniform(-0.02, 0.02),
        "bumps_m": {s: r.uniform(-1.5e-3, 1.5e-3) for s in SITES}, "bump_w": 0.02,
        "form": "z_c + tilt·X − X²/2Rx − Y²/2Ry + Σ_sites bump·exp(−r²/2w²)",
    }
    S["geom"] = geom
    S["dataset_meta"] = {
        "nominal_surface_z": geom["z_center"] + r.normal(0, 0.8e-3),
        "torso_center_xy": [cx + r.normal(0, 2e-3), cy + r.normal(0, 2e-3)],
    }
    S["body"] = {
        "K_n_per_m": r.uniform(450, 1300), "layer_thickness_m": r.uniform(0.07, 0.11),
        "c_lin_ns_per_m": r.uniform(15, 45), "mu0": r.uniform(0.095, 0.105),
        "b0_ns_per_m": r.uniform(0.0, 0.5), "bristle_sigma0_per_m": r.uniform(700, 1500),
        "contact_roughness_m": 5e-5,
        "form": ("F_n = S·K·N(w)·H·ln(H/(H−w))/w + Σh_i + c(δ)·u̇ − m·ẍ_tissue; "
                 "w = face-mean of softplus(u − g(ξ)); none: N(w)=w, S=1, no h, c=c_lin, m=0; "
                 "friction LuGre bristle, μ0 (≈0.1) + b0·v"),
    }
    S["probe"] = {
        "face_length_m": r.uniform(0.030, 0.045), "face_width_m": r.uniform(0.010, 0.014),
        "lens_radius_m": r.uniform(0.04, 0.08), "face_axis_angle_rad": r.uniform(0, math.pi),
        "sensor_lever_m": r.uniform(0.10, 0.16),
    }
    tcp_dir = r.normal(size=3); tcp_dir /= np.linalg.norm(tcp_dir)
    S["robot"] = {
        "k_arm_n_per_m": r.uniform(2.0e4, 4.0e4), "tau_arm_s": r.uniform(0.012, 0.02),
        "servo_hz": r.uniform(10, 20), "servo_zeta": r.uniform(0.8, 1.0),
        "tcp_offset_m": (tcp_dir * r.uniform(2e-4, 8e-4)).tolist(),
        "encoder_sigma_m": r.uniform(3e-6, 1e-5), "encoder_quantum_m": 1e-6,
        "velocity_sigma_m_per_s": r.uniform(1e-4, 4e-4),
        "residual_probe_mass_kg": r.uniform(-0.008, 0.008),
        "gravity_comp_mass_error_kg": r.uniform(-0.002, 0.002),
        "gravity_comp_sensor_frame_residual_n": r.uniform(-0.03, 0.03, 3).tolist(),
        "transport_latency_s": r.uniform(0.0005, 0.0015),
        "surface_estimate_sigma_m": 0.6e-3,
    }
    sz = r.uniform(0.02, 0.045)
    sxy = sz * r.uniform(0.7, 1.0)
    S["noise"] = {
        "sigma_total_n": [sxy, sxy * r.uniform(0.9, 1.1), sz],
        "white_fraction": r.uniform(0.3, 0.7), "ar_corr_time_s": r.uniform(0.005, 0.03),
        "quantum_n": r.uniform(0.002, 0.006),
        "torque_sigma_nm": r.uniform(5e-4, 2e-3),
        "form": "white + AR(1) (correlation time) per axis, rounded to the sensor quantum",
    }
    # logger
    rates = [66.7, 100.0, 125.0, 250.0, 500.0, 1000.0]
    mixed = r.random() < 0.35
    base_rate = float(r.choice(rates, p=[0.08, 0.17, 0.2, 0.2, 0.2, 0.15]))
    use_session_time = bool(r.random() < 0.6)
    S["logger"] = {"mixed_rates": mixed, "base_rate_hz": base_rate,
                   "session_time_s_written": use_session_time,
                   "jitter_frac": r.uniform(0.02, 0.12),
                   "t0_style": str(r.choice(["zero", "offset"]))}
    # lab's surface estimates per site (what it plans with)
    est = {}
    for s, (ox, oy) in SITES.items():
        z, _, _ = surface(geom, cx + ox, cy + oy)
        est[s] = float(z) + r.normal(0, S["robot"]["surface_estimate_sigma_m"])
    S["surface_estimate"] = {"per_site_z": est, "plane_err": r.normal(0, [3e-4, 0.004, 0.004]).tolist()}
    S["true_site_z"] = {s: float(surface(geom, cx + ox, cy + oy)[0]) for s, (ox, oy) in SITES.items()}
    build_recordings(S, r)
    return S


def est_surface(S, x, y):
    """The lab's surface model: truth + a small plane error (for slides and hovering)."""
    z, _, _ = surface(S["geom"], x, y)
    e0, ex, ey = S["surface_estimate"]["plane_err"]
    cx, cy = S["geom"]["center_xy"]
    return z + e0 + ex * (np.asarray(x) - cx) + ey * (np.asarray(y) - cy)


KINDS = ["press_ramp", "staircase", "indent_series", "chirp", "palpation",
         "force_press", "force_slide", "pos_slide"]
PROTO = {"press_ramp": "press", "staircase": "press", "indent_series": "press",
         "chirp": "chirp", "palpation": "chirp", "force_press": "press",
         "force_slide": "slide", "pos_slide": "slide"}


def build_recordings(S, r):
    n_rec = int(r.integers(6, 15))
    budget = r.uniform(110, 160)
    scale = float(np.clip(budget / n_rec / 19.0, 0.45, 1.4))
    kinds = ["press_ramp", "chirp", "chirp", "force_press", "force_slide",
             str(r.choice(["staircase", "indent_series"]))]
    n_mand = len(kinds)
    extra_p = np.array([3, 2, 2, 2, 1, 2, 1, 1], float)
    while len(kinds) < n_rec:
        kinds.append(str(r.choice(KINDS, p=extra_p / extra_p.sum())))
    order = r.permutation(len(kinds))
    mandatory = [bool(i < n_mand) for i in order]
    kinds = [kinds[i] for i in order]
    site_names = list(SITES)
    site_p = np.array([2, 1, 1, 1, 1], float); site_p /= site_p.sum()
    K = S["body"]["K_n_per_m"]
    recs = []
    for i, kind in enumerate(kinds):
        site = str(r.choice(site_names, p=site_p))
        recs.append(make_recording(S, r, i, kind, site, scale, K))
    # the first chirp is always a linear sweep (most of its time at the high frequencies)
    ch = [rc for rc in recs if rc["kind"] == "chirp"]
    if ch:
        ch[0]["params"]["sweep"] = "linear"
    # at least three distinct sites among the presses
    press_sites = {rc["site"] for rc in recs}
    spare = [s for s in site_names if s not in press_sites]
    k = 0
    while len({rc["site"] for rc in recs}) < 3 and spare:
        rc = recs[k % len(recs)]
        new = spare.pop()
        recs[k % len(recs)] = make_recording(S, r, rc["index"], rc["kind"], new, scale, K)
        k += 1
    # keep the recorded time within the budget (drop optional recordings, last first)
    while sum(rc["duration_s"] for rc in recs) > 165.0 and len(recs) > 6:
        opt = [i for i, rc in enumerate(recs) if not mandatory[i]]
        if not opt:
            break
        recs.pop(opt[-1]); mandatory.pop(opt[-1])
    for i, rc in enumerate(recs):
        rc["index"] = i
    # session timing
    D = np.array([rc["duration_s"] for rc in recs])
    if S["logger"]["session_time_s_written"]:
        span = max(r.uniform(150, 300), D.sum() + 2 * (len(recs) - 1))
        gaps = r.dirichlet(np.ones(len(recs) - 1)) * (span - D.sum())
        gaps = np.maximum(gaps, 2.0)
    else:
        gaps = r.uniform(0.5, 2.5, len(recs) - 1)   # back to back
        short = 150.0 - (D.sum() + gaps.sum())
        if short > 0:
            gaps = gaps + short / len(gaps)
    t0 = r.uniform(5, 40)   # session clock at the first recording's start
    starts = np.concatenate([[t0], t0 + np.cumsum(D[:-1] + gaps)])
    rates = [66.7, 100.0, 125.0, 250.0, 500.0, 1000.0]
    for rc, T0 in zip(recs, starts):
        rc["session_start_s"] = float(T0)
        rate = float(r.choice(rates)) if S["logger"]["mixed_rates"] else S["logger"]["base_rate_hz"]
        if rc["kind"] in ("chirp", "palpation") and rate < 100:
            rate = 100.0 if r.random() < 0.5 else rate
        make_sampling(S, r, rc, rate)
        rc["file"] = f"{rc['index'] + 1:02d}_{rc['site']}_{PROTO[rc['kind']]}.csv"
    S["recordings"] = recs


def make_recording(S, r, index, kind, site, scale, K):
    cx, cy = S["geom"]["center_xy"]
    ox, oy = SITES[site]
    px, py = cx + ox + r.normal(0, 2e-3), cy + oy + r.normal(0, 2e-3)
    z_est = S["surface_estimate"]["per_site_z"][site]
    dmax = min(0.014, 13.0 / K)
    rc = {"index": index, "kind": kind, "site": site, "protocol": PROTO[kind],
          "mode": "force" if kind.startswith("force") else "position",
          "press_xy": [px, py]}
    hov = r.uniform(3e-3, 6e-3)
    tw0, tw1 = r.uniform(0.8, 1.5), r.uniform(0.8, 1.5)
    P = {}
    if kind == "press_ramp":
        d = r.uniform(0.005, dmax)
        vin, vout = r.uniform(2e-3, 8e-3), r.uniform(3e-3, 1e-2)
        hold = r.uniform(3, 8) * scale
        zs, zb = z_est + hov, z_est - d
        t1 = tw0 + (zs - zb) / vin; t2 = t1 + hold; t3 = t2 + (zs - zb) / vout
        P = {"depth_cmd_m": d, "v_in": vin, "v_out": vout, "hold_s": hold,
             "wps": [(0, zs), (tw0, zs), (t1, zb), (t2, zb), (t3, zs)]}
        D = t3 + tw1
    elif kind == "staircase":
        n = int(r.integers(3, 6)); step = min(r.uniform(2e-3, 3.5e-3), dmax / n)
        holds = r.uniform(1.5, 4.0, n) * scale
        zs = z_est + hov
        wps = [(0, zs), (tw0, zs)]
        t = tw0 + (hov + step) / 4e-3
        z = z_est - step
        wps.append((t, z))
        for k in range(n):
            t += holds[k]; wps.append((t, z))
            if k < n - 1:
                t += step / 4e-3; z -= step; wps.append((t, z))
        t += (zs - z) / 5e-3; wps.append((t, zs))
        P = {"steps": n, "step_m": step, "holds_s": holds.tolist(), "wps": wps}
        D = t + tw1
    elif kind == "indent_series":
        n = int(r.integers(4, 7)); h = r.uniform(2e-3, 3e-3)
        zs = z_est + h
        wps = [(0, zs), (tw0, zs)]; t = tw0
        depths, speeds = [], []
        for k in range(n):
            d = r.uniform(0.004, min(0.009, dmax))
            v = r.uniform(1.5e-3, 3e-3) if k % 2 == 0 else r.uniform(0.015, 0.03)
            t += (h + d) / v; wps.append((t, z_est - d))
            t += r.uniform(0.0, 0.3); wps.append((t, z_est - d))
            t += (h + d) / v; wps.append((t, zs))
            t += r.uniform(0.5, 1.0); wps.append((t, zs))
            depths.append(d); speeds.append(v)
        P = {"depths_m": depths, "speeds_m_per_s": speeds, "hover_m": h, "wps": wps}
        D = t + tw1 * 0.5
    elif kind in ("chirp", "palpation"):
        pre = r.uniform(0.004, min(0.008, dmax * 0.7))
        zs, zb = z_est + hov, z_est - pre
        t1 = tw0 + (zs - zb) / 4e-3
        settle = r.uniform(1.0, 2.0)
        if kind == "chirp":
            f0, f1 = r.uniform(0.2, 0.5), r.uniform(6.0, 10.0)
            amp = r.uniform(0.8e-3, 2.0e-3)
            Tc = r.uniform(14, 24)
            P = {"pre_depth_m": pre, "f0_hz": f0, "f1_hz": f1, "amp_m": amp, "T_s": Tc,
                 "sweep": str(r.choice(["exponential", "linear"])),
                 "robot_accel_limit_m_per_s2": r.uniform(4.0, 7.0),
                 "amplitude_law": "min(amp, a_max/(2πf)²)"}
        else:
            f0 = r.uniform(1.5, 4.0); f1 = f0 * r.uniform(1.3, 2.2)
            amp = min(r.uniform(1.5e-3, 3.0e-3), 5.0 / (2 * math.pi * f0) ** 2)
            Tc = r.uniform(6, 12) * min(scale, 1.0) + 3
            P = {"pre_depth_m": pre, "f_hz": [f0, f1], "amp_m": amp, "T_s": Tc,
                 "amp_ratio_second_tone": r.uniform(0.3, 0.5), "phase2": r.uniform(0, 6.28),
                 "depth_trend_m": r.uniform(-1e-3, 1e-3)}
        tc0 = t1 + settle; tc1 = tc0 + Tc
        t3 = tc1 + settle * 0.5 + (zs - zb) / 5e-3
        P.update({"wps": [(0, zs), (tw0, zs), (t1, zb), (tc1 + settle * 0.5, zb), (t3, zs)],
                  "t_osc": [tc0, tc1]})
        D = t3 + tw1
    elif kind == "force_press":
        Ft = r.uniform(4.0, 12.0)
        vapp = r.uniform(3e-3, 5e-3)
        T_ramp = r.uniform(1.0, 3.0); hold = r.uniform(5, 10) * scale
        z_start = z_est + hov
        t_contact_est = tw0 + hov / vapp
        T_rel = t_contact_est + 0.5 + T_ramp + hold
        P = {"F_target_n": Ft, "v_approach": vapp, "T_ramp_s": T_ramp, "hold_s": hold,
             "z_start": z_start, "t_start_approach": tw0, "T_release_s": T_rel,
             "T_down_s": 1.0, "v_retract": 1e-2}
        D = T_rel + 1.0 + 1.8 + tw1 * 0.5
    elif kind == "force_slide":
        Ft = r.uniform(4.0, 6.0)
        vapp = r.uniform(3e-3, 5e-3)
        T_ramp = r.uniform(0.8, 1.5)
        L = r.uniform(0.03, 0.08); v = r.uniform(8e-3, 2e-2)
        back = bool(r.random() < 0.5)
        z_start = z_est + hov
        t_lat = tw0 + hov / vapp + T_ramp + 2.0
        leg = 1.875 * L / v
        t_end_lat = t_lat + leg * (2 if back else 1) + (0.3 if back else 0)
        T_rel = t_end_lat + 0.7
        ang = r.uniform(-0.5, 0.5) + (0 if r.random() < 0.7 else math.pi / 2)
        P = {"F_target_n": Ft, "v_approach": vapp, "T_ramp_s": T_ramp, "z_start": z_start,
             "t_start_approach": tw0, "T_release_s": T_rel, "T_down_s": 0.8,
             "v_retract": 1e-2, "path_len_m": L, "speed_m_per_s": v, "there_and_back": back,
             "path_angle_rad": ang, "t_lateral": [t_lat, t_end_lat]}
        D = T_rel + 0.8 + 1.6 + tw1 * 0.5
    elif kind == "pos_slide":
        L = r.uniform(0.03, 0.07); v = r.uniform(8e-3, 1.8e-2)
        d = r.uniform(0.003, min(0.006, dmax))
        back = bool(r.random() < 0.5)
        ang = r.uniform(-0.5, 0.5) + (0 if r.random() < 0.7 else math.pi / 2)
        t_dn = tw0 + (hov + d) / 4e-3
        t_lat = t_dn + 1.0
        leg = 1.875 * L / v
        t_end_lat = t_lat + leg * (2 if back else 1) + (0.3 if back else 0)
        P = {"depth_cmd_m": d, "path_len_m": L, "speed_m_per_s": v, "there_and_back": back,
             "path_angle_rad": ang, "t_lateral": [t_lat, t_end_lat], "hover_m": hov,
             "t_down": [tw0, t_dn], "t_up": [t_end_lat + 0.5, t_end_lat + 0.5 + (hov + d) / 5e-3]}
        D = P["t_up"][1] + tw1
    rc["params"] = P
    rc["duration_s"] = float(D)
    # probe orientation: lab aligns the probe with its surface model's normal at the
    # site, residual misalignment 0.5–2° (in a random direction)
    _, gx, gy = surface(S["geom"], px, py)
    n = normal_from_grad(gx, gy)
    mis = math.radians(r.uniform(0.5, 2.0)); mdir = r.uniform(0, 2 * math.pi)
    rc["misalignment_rad"] = [mis * math.cos(mdir), mis * math.sin(mdir)]
    axis = n + np.array([rc["misalignment_rad"][0], rc["misalignment_rad"][1], 0.0])
    rc["probe_axis"] = (axis / np.linalg.norm(axis)).tolist()
    rc["columns_velocity"] = bool(r.random() < 0.4)
    rc["columns_torque"] = bool(r.random() < 0.35)
    return rc


def rot_z_to(a):
    """Rotation taking ẑ onto unit vector a (Rodrigues)."""
    a = np.asarray(a, float); z = np.array([0, 0, 1.0])
    v = np.cross(z, a); s = np.linalg.norm(v); c = float(a @ z)
    if s < 1e-12:
        return np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx * ((1 - c) / s ** 2)


def make_sampling(S, r, rc, rate):
    D = rc["duration_s"]
    dt = 1.0 / rate
    jf = S["logger"]["jitter_frac"]
    k = np.arange(int(math.floor((D - 0.01) * rate)))
    jit = np.clip(r.normal(0, jf, len(k)), -0.4, 0.4) * dt
    tacq = k * dt + 0.5 * dt + jit
    tacq = tacq[(tacq > 0) & (tacq < D - DT * 2)]
    gap = None
    if r.random() < 0.3:
        thr = max(GAP_FACTOR * dt, GAP_MIN_S)
        glen = thr * r.uniform(1.6, 4.0)
        gs = r.uniform(0.3, 0.7) * D
        keep = (tacq < gs) | (tacq > gs + glen)
        gap = {"start_s": float(gs), "length_s": float(glen)}
        tacq = tacq[keep]
    t_off = 0.0 if S["logger"]["t0_style"] == "zero" else float(r.uniform(0.0, 3.0))
    stamps = np.round(tacq + t_off, 6)
    assert np.all(np.diff(stamps) > 0)
    Kn = len(tacq)
    nz = S["noise"]
    sig = np.array(nz["sigma_total_n"])
    wf = nz["white_fraction"]
    rho = math.exp(-dt / nz["ar_corr_time_s"])
    white = r.normal(size=(Kn, 3)) * sig * math.sqrt(wf)
    inno = r.normal(size=(Kn, 3)) * sig * math.sqrt((1 - wf) * (1 - rho ** 2))
    ar = np.empty((Kn, 3)); st = r.normal(size=3) * sig * math.sqrt(1 - wf)
    for i in range(Kn):
        st = rho * st + inno[i]; ar[i] = st
    rc["sampling"] = {"rate_hz": rate, "n": Kn, "t_offset_s": t_off, "gap": gap,
                      "jitter_frac": jf, "first_acq_s": float(tacq[0])}
    rc["_tacq"] = tacq
    rc["_stamps"] = stamps
    rc["_fnoise"] = white + ar
    rc["_pnoise"] = r.normal(size=(Kn, 3)) * S["robot"]["encoder_sigma_m"]
    rc["_vnoise"] = r.normal(size=(Kn, 3)) * S["robot"]["velocity_sigma_m_per_s"]
    rc["_tqnoise"] = r.normal(size=(Kn, 3)) * nz["torque_sigma_nm"]
    if rc["mode"] == "force":
        cr = float(r.choice([250.0, 500.0, 1000.0]))
        nt = int(D * cr) + 2
        rc["ctrl"] = {"rate_hz": cr, "bandwidth_hz": r.uniform(0.8, 2.0),
                      "assumed_stiffness_n_per_m": 1000.0, "force_lpf_hz": r.uniform(10, 25),
                      "v_max": r.uniform(0.012, 0.02), "F_contact_n": 1.0}
        rc["_cnoise"] = r.normal(size=nt) * sig[2]
    # orientation-dependent residual of the lab's gravity compensation (world frame)
    Rm = rot_z_to(rc["probe_axis"])
    rs = np.array(S["robot"]["gravity_comp_sensor_frame_residual_n"])
    rc["grav_residual_n"] = (Rm @ rs - rs + np.array([0, 0, -S["robot"]["gravity_comp_mass_error_kg"] * G])).tolist()


# ----------------------------------------------------------------------------- effects

def draw_effect(name, seed, S):
    """Parameters of one effect, from its own stream (same alone and in a pair)."""
    r = rng_for(seed, 1000 + CATALOGUE.index(name))
    recs = S["recordings"]
    t_first = min(rc["session_start_s"] + rc["_tacq"][0] for rc in recs)
    t_last = max(rc["session_start_s"] + rc["_tacq"][-1] for rc in recs)
    p = {}
    if name == "sensor_bias":
        if r.random() < 0.5:
            m = r.uniform(0.12, 0.30)
            p = {"form": "untared_probe_weight", "mass_kg": m,
                 "world_offset_n": [r.uniform(-0.1, 0.1), r.uniform(-0.1, 0.1), -m * G]}
        else:
            bz = r.uniform(0.6, 2.0) * (1 if r.random() < 0.5 else -1)
            p = {"form": "thermal_zero_offset_sensor_frame",
                 "sensor_frame_offset_n": [r.uniform(-0.3, 0.3), r.uniform(-0.3, 0.3), bz]}
    elif name == "sensor_delay":
        lat = r.uniform(0.015, 0.05)
        zoh = float(r.choice([0.0, 100.0, 125.0, 200.0, 250.0], p=[0.4, 0.15, 0.15, 0.15, 0.15]))
        p = {"form": "bus latency + zero-order hold at the sensor's internal clock",
             "latency_s": lat, "internal_rate_hz": zoh, "zoh_phase": r.uniform(0, 1)}
    elif name == "tissue_inertia":
        p = {"form": "tissue mass dragged with the probe on a stiff coupling",
             "moving_mass_kg": r.uniform(0.3, 0.6), "coupling_hz": r.uniform(18, 35),
             "coupling_zeta": r.uniform(0.4, 0.8)}
    elif name == "nonlinear_stiffness":
        form = str(r.choice(["fung_exponential", "power_law", "toe_linear", "polynomial"]))
        p = {"form": form, "w_ref_m": 0.005}
        if form == "fung_exponential":
            p["d0_m"] = r.uniform(0.005, 0.010)
        elif form == "power_law":
            p["n"] = r.uniform(1.35, 1.7)
        elif form == "toe_linear":
            p["toe_m"] = r.uniform(0.0025, 0.004)
        else:
            p["d1_m"] = r.uniform(0.005, 0.010); p["d2_m"] = r.uniform(0.012, 0.02)
    elif name == "viscoelastic_relaxation":
        form = str(r.choice(["prony2", "prony3", "box_spectrum"], p=[0.4, 0.3, 0.3]))
        if form == "prony2":
            taus = [r.uniform(0.3, 1.5), r.uniform(4, 15)]
            ratios = [r.uniform(0.15, 0.5), r.uniform(0.15, 0.5)]
        elif form == "prony3":
            taus = [r.uniform(0.1, 0.3), r.uniform(1.0, 3.0), r.uniform(8, 20)]
            ratios = list(r.uniform(0.1, 0.35, 3))
        else:
            t1, t2 = r.uniform(0.05, 0.3), r.uniform(8, 25)
            tot = r.uniform(0.4, 1.0)
            edges = np.geomspace(t1, t2, NB + 1)
            taus = list(np.sqrt(edges[:-1] * edges[1:]))
            ratios = [tot / NB] * NB   # equal weight per log-interval: Fung's box spectrum
            p.update({"tau1_s": t1, "tau2_s": t2, "C_per_decade_ln": tot / math.log(t2 / t1)})
        p.update({"form": form, "taus_s": taus, "ratios": ratios,
                  "law": "F = F_e + Σ h_i, ḣ_i = −h_i/τ_i + r_i·Ḟ_e (QLV, relaxed = F_e)"})
    elif name == "breathing_motion":
        p = draw_breathing(r, t_first, t_last)
    elif name == "site_heterogeneity":
        pressed = sorted({rc["site"] for rc in recs if rc["protocol"] == "press"})
        if r.random() < 0.5:
            site = str(r.choice(pressed))
            p = {"form": "stiff_inclusion", "site": site, "gain": r.uniform(0.8, 1.6),
                 "depth_scale_m": r.uniform(0.003, 0.007), "radius_m": r.uniform(0.012, 0.025),
                 "law": "S = 1 + gain·exp(−r²/2R²)·(1 − exp(−δ/d_c))"}
        else:
            ang = r.uniform(0, 2 * math.pi)
            span = r.uniform(1.6, 2.6)   # ratio between the extreme sites
            proj = [SITES[s][0] * math.cos(ang) + SITES[s][1] * math.sin(ang) for s in SITES]
            g = math.log(span) / (max(proj) - min(proj))
            p = {"form": "smooth_gradient", "angle_rad": ang, "log_gradient_per_m": g,
                 "law": "S = exp(g·(X cos a + Y sin a))"}
    elif name == "sliding_friction":
        if r.random() < 0.55:
            mu = r.uniform(0.22, 0.45)
            p = {"form": "stribeck_lugre", "mu_c": mu, "mu_s": mu * r.uniform(1.2, 1.6),
                 "v_stribeck_m_per_s": r.uniform(1e-3, 5e-3), "b_ns_per_m": r.uniform(2, 10)}
        else:
            p = {"form": "lubricated_film", "mu_c": r.uniform(0.13, 0.18), "mu_s": None,
                 "v_stribeck_m_per_s": 3e-3, "b_ns_per_m": r.uniform(30, 60)}
            p["mu_s"] = p["mu_c"]
    elif name == "sensor_filter":
        form = str(r.choice(["butterworth2", "one_pole", "two_equal_poles", "moving_average"]))
        p = {"form": form}
        if form == "butterworth2":
            p["fc_hz"] = r.uniform(4, 14)
        elif form == "one_pole":
            p["fc_hz"] = r.uniform(3, 9)
        elif form == "two_equal_poles":
            p["fc_hz"] = r.uniform(4, 12)
        else:
            p["window_s"] = r.uniform(0.030, 0.080); p["internal_rate_hz"] = 2000.0
    elif name == "bias_drift":
        form = str(r.choice(["linear", "settling", "linear_thermal_wobble"]))
        span = t_last - t_first
        total = r.uniform(0.3, 0.8) * (1 if r.random() < 0.5 else -1)
        t_tare = t_first - r.uniform(3, 20)
        p = {"form": form, "t_tare_s": t_tare, "xy_fraction": r.uniform(-0.3, 0.3, 2).tolist()}
        if form == "linear":
            p["rate_n_per_s"] = total / span
        elif form == "settling":
            tau = r.uniform(60, 200)
            t_on = t_first - r.uniform(0, 60)
            p["settle_s"] = tau; p["t_power_on_s"] = t_on
            p["D_inf_n"] = total / (math.exp(-(t_first - t_on) / tau) - math.exp(-(t_last - t_on) / tau))
        else:
            p["rate_n_per_s"] = total / span
            p["wobble_n"] = r.uniform(0.05, 0.15); p["wobble_period_s"] = r.uniform(200, 600)
            p["wobble_phase"] = r.uniform(0, 2 * math.pi)
    elif name == "depth_dependent_damping":
        pe = r.uniform(1.0, 1.6); ratio = r.uniform(1.8, 4.0)
        c_lin = S["body"]["c_lin_ns_per_m"]
        p = {"form": "hunt_crossley", "exponent": pe, "ratio_at_10mm": ratio,
             "c_hc": ratio * c_lin / 0.01 ** pe,
             "law": "F_d = (c_lin + c_hc·δ^p)·u̇"}
    return p


def breath_profile(phi, q, pz):
    """One cycle on phase phi∈[0,1): inhale share q, end-exhale pause share pz; values in
    [−1, 1] (−1: end-exhale); exhale fast then slowly settling (Lujan-like dwell)."""
    e = 1.0 - q - pz
    b = np.full_like(phi, -1.0)
    m1 = phi < q
    b[m1] = -np.cos(math.pi * phi[m1] / q)
    m2 = (phi >= q) & (phi < q + e)
    s = (phi[m2] - q) / e
    b[m2] = -1 + 2 * ((1 + np.cos(math.pi * s)) / 2) ** 1.6
    return b


def draw_breathing(r, t_first, t_last):
    f = r.uniform(0.2, 0.33)
    q, pz = r.uniform(0.35, 0.45), r.uniform(0.05, 0.22)
    cv, acv = r.uniform(0.04, 0.10), r.uniform(0.05, 0.12)
    sigh_p = r.uniform(0.05, 0.12)
    A = r.uniform(1.5e-3, 4.5e-3)
    starts, periods, scales, sighs = [], [], [], []
    t = t_first - r.uniform(0, 1 / f) - 5
    x = 0.0
    while t < t_last + 5:
        x = 0.7 * x + math.sqrt(1 - 0.49) * r.normal()   # rate drifting (AR(1) on periods)
        T = (1 / f) * (1 + cv * x)
        a = 1 + acv * r.normal()
        sigh = r.random() < sigh_p
        if sigh:
            T *= r.uniform(1.3, 1.6); a *= r.uniform(1.6, 2.0)
        starts.append(t); periods.append(T); scales.append(a); sighs.append(bool(sigh))
        t += T
    starts, periods, scales = map(np.array, (starts, periods, scales))
    inside = (starts + periods > t_first) & (starts < t_last)
    normal_sc = scales[inside & ~np.array(sighs)]
    p = {"form": "irregular asymmetric breaths (inhale share, end-exhale pause, rate drift, sighs)",
         "A_center_m": A, "inhale_share": q, "pause_share": pz, "period_cv": cv,
         "amplitude_cv": acv, "sigh_prob": sigh_p, "edge_ratio": r.uniform(0.45, 1.0),
         "lateral_ratio": r.uniform(0.1, 0.25), "craniocaudal_ratio": r.uniform(0.05, 0.15),
         "starts_s": starts.tolist(), "periods_s": periods.tolist(), "scales": scales.tolist(),
         "sighs": sighs, "mean_rate_hz": float(1.0 / periods[inside].mean()),
         "typical_half_p2p_m": float(A * np.median(normal_sc if len(normal_sc) else scales[inside])),
         "law": "z_b = A(X,Y)·(−1 + a_k(b(φ)+1)) − mean; A(X,Y) = A_c(1 − (1−e)ρ²), ρ²=((X/6cm)²+(Y/8cm)²)/2"}
    # the session mean of the waveform (removed so the surface moves about its rest mean)
    tt = np.arange(t_first, t_last, 0.05)
    p["mean_offset_unit"] = float(breath_unit(p, tt)[0].mean())
    return p


def breath_unit(p, t):
    """Unit-amplitude centre breathing displacement and its rate at session times t."""
    starts = np.asarray(p["starts_s"]); periods = np.asarray(p["periods_s"])
    scales = np.asarray(p["scales"])
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
    phi = np.clip((t - starts[k]) / periods[k], 0, 0.999999)
    b = breath_profile(phi, p["inhale_share"], p["pause_share"])
    z = -1 + scales[k] * (b + 1) - p.get("mean_offset_unit", 0.0)
    h = 1e-3
    phi2 = np.clip((t + h - starts[k]) / periods[k], 0, 0.999999)
    b2 = breath_profile(phi2, p["inhale_share"], p["pause_share"])
    zd = scales[k] * (b2 - b) / h
    return z, zd


# ----------------------------------------------------------------------------- laws

def nonlin_N(p, w):
    """Effect's stiffening law of the face-mean indentation w (normalised N(w_ref)=w_ref)."""
    if p is None:
        return w
    wr = p["w_ref_m"]
    f = p["form"]
    if f == "fung_exponential":
        d0 = p["d0_m"]; g = lambda x: d0 * np.expm1(x / d0)
    elif f == "power_law":
        g = lambda x: np.maximum(x, 0) ** p["n"]
    elif f == "toe_linear":
        dt_ = p["toe_m"]; g = lambda x: x - dt_ * (1 - np.exp(-x / dt_))
    else:
        g = lambda x: x + x ** 2 / p["d1_m"] + x ** 3 / p["d2_m"] ** 2
    return g(np.maximum(w, 0)) * (wr / g(np.array(wr)))


def contact_table(S, rc):
    """Face-mean indentation w(u) of the probe face, u = indentation at the face centre."""
    pr = S["probe"]; geom = S["geom"]
    L, W = pr["face_length_m"], pr["face_width_m"]
    a = pr["face_axis_angle_rad"]
    xs = np.linspace(-L / 2, L / 2, 13); ys = np.linspace(-W / 2, W / 2, 7)
    XI, ETA = np.meshgrid(xs, ys)
    # face shape: cylindrical lens across the width
    g = ETA ** 2 / (2 * pr["lens_radius_m"])
    # world offsets of face points, relative misalignment tilt, surface curvature
    dx = XI * math.cos(a) - ETA * math.sin(a); dy = XI * math.sin(a) + ETA * math.cos(a)
    mx, my = rc["misalignment_rad"]
    g = g + mx * dx + my * dy + dx ** 2 / (2 * geom["Rx"]) + dy ** 2 / (2 * geom["Ry"])
    g = g.ravel()
    u_touch = float(g.min())
    u = u_touch - N_PRE * DU + np.arange(int(0.045 / DU) + N_PRE) * DU
    sr = S["body"]["contact_roughness_m"]
    w = np.mean(softplus(u[:, None] - g[None, :], sr), axis=1)
    w -= w[N_PRE]
    w[:N_PRE + 1] = 0.0     # exactly no force up to first touch (index N_PRE)
    return u, np.maximum(w, 0.0), u_touch


def elastic_from_w(S, w, nl):
    K = S["body"]["K_n_per_m"]; H = S["body"]["layer_thickness_m"]
    wc = np.minimum(w, 0.6 * H)
    thin = np.where(wc > 1e-9, H * np.log(H / (H - wc)) / np.maximum(wc, 1e-12), 1.0)
    return K * nonlin_N(nl, w) * thin


def loglog_slope(d, F, dmax):
    m = (d >= 0.002) & (d <= dmax) & (F > 0)
    if m.sum() < 3 or dmax <= 0.0025:
        return None, None
    dd = np.geomspace(0.002, dmax, 40)
    FF = np.interp(dd, d, F)
    slope = np.polyfit(np.log(dd), np.log(FF), 1)[0]
    two = math.log(FF[-1] / FF[0]) / math.log(dd[-1] / dd[0])
    return float(slope), float(two)


def filter_coeffs(p):
    """(b0,b1,b2,a1,a2, W) of the sensor filter on the DT grid."""
    if p is None:
        return (1.0, 0.0, 0.0, 0.0, 0.0, 1)
    f = p["form"]
    if f == "butterworth2":
        K = math.tan(math.pi * p["fc_hz"] * DT); q = math.sqrt(2)
        nrm = 1 / (1 + q * K + K * K)
        b0 = K * K * nrm
        return (b0, 2 * b0, b0, 2 * (K * K - 1) * nrm, (1 - q * K + K * K) * nrm, 1)
    if f == "one_pole":
        al = math.exp(-2 * math.pi * p["fc_hz"] * DT)
        return (1 - al, 0.0, 0.0, -al, 0.0, 1)
    if f == "two_equal_poles":
        fp = p["fc_hz"] / math.sqrt(math.sqrt(2) - 1)
        al = math.exp(-2 * math.pi * fp * DT)
        return ((1 - al) ** 2, 0.0, 0.0, -2 * al, al * al, 1)
    W = max(1, int(round(p["window_s"] / DT)))
    return (1.0, 0.0, 0.0, 0.0, 0.0, W)


def filter_cutoff(p):
    b0, b1, b2, a1, a2, W = filter_coeffs(p)
    f = np.linspace(0.01, 200, 200000)
    z = np.exp(-2j * math.pi * f * DT)
    H = (b0 + b1 * z + b2 * z * z) / (1 + a1 * z + a2 * z * z)
    if W > 1:
        H = H * (1 - z ** W) / (W * (1 - z))
    mag = np.abs(H)
    i = int(np.argmax(mag < 1 / math.sqrt(2)))
    return float(f[i])


def drift_fn(p, t):
    """Drift of the sensor zero (z) at session times t, relative to the tare."""
    t = np.asarray(t, float)

    def raw(tt):
        if p["form"] == "linear":
            return p["rate_n_per_s"] * tt
        if p["form"] == "settling":
            return p["D_inf_n"] * (1 - np.exp(-(tt - p["t_power_on_s"]) / p["settle_s"]))
        return p["rate_n_per_s"] * tt + p["wobble_n"] * np.sin(
            2 * math.pi * tt / p["wobble_period_s"] + p["wobble_phase"])
    return raw(t) - raw(np.array(p["t_tare_s"]))


# ----------------------------------------------------------------------------- simulate

class CaseParams:
    def __init__(self, S, effects):
        self.effects = effects   # name -> params
        e = effects
        self.nl = e.get("nonlinear_stiffness")
        ve = e.get("viscoelastic_relaxation")
        self.r = np.zeros(NB); self.tau = np.ones(NB)
        if ve:
            n = len(ve["taus_s"])
            self.r[:n] = ve["ratios"]; self.tau[:n] = ve["taus_s"]
        ti = e.get("tissue_inertia")
        self.m_t = ti["moving_mass_kg"] if ti else 0.0
        self.w_t = 2 * math.pi * (ti["coupling_hz"] if ti else 25.0)
        self.z_t = ti["coupling_zeta"] if ti else 0.6
        self.breath = e.get("breathing_motion")
        self.site = e.get("site_heterogeneity")
        fr = e.get("sliding_friction")
        b = S["body"]
        if fr:
            self.mu_c, self.mu_s = fr["mu_c"], fr["mu_s"]
            self.vs, self.b = fr["v_stribeck_m_per_s"], b["b0_ns_per_m"] + fr["b_ns_per_m"]
        else:
            self.mu_c = self.mu_s = b["mu0"]; self.vs = 3e-3; self.b = b["b0_ns_per_m"]
        self.filt = filter_coeffs(e.get("sensor_filter"))
        sd = e.get("sensor_delay")
        lat0 = S["robot"]["transport_latency_s"]
        if sd:
            self.lat = int(round((lat0 + sd["latency_s"]) / DT))
            self.m_zoh = int(round(2000.0 / sd["internal_rate_hz"])) if sd["internal_rate_hz"] else 1
            self.ph = int(sd["zoh_phase"] * self.m_zoh)
        else:
            self.lat = int(round(lat0 / DT)); self.m_zoh = 1; self.ph = 0
        dd = e.get("depth_dependent_damping")
        self.c_hc = dd["c_hc"] if dd else 0.0
        self.p_hc = dd["exponent"] if dd else 1.0
        self.bias = e.get("sensor_bias")
        self.drift = e.get("bias_drift")


def case_bias_world(cp, rc):
    if cp.bias is None:
        return np.zeros(3)
    if cp.bias["form"] == "untared_probe_weight":
        return np.array(cp.bias["world_offset_n"])
    return rot_z_to(rc["probe_axis"]) @ np.array(cp.bias["sensor_frame_offset_n"])


def site_factors(cp, S, xm, ym):
    """Spatial part of the stiffness scale, and the inclusion's footprint, along a path."""
    cx, cy = S["geom"]["center_xy"]
    X, Y = xm - cx, ym - cy
    if cp.site is None:
        return np.ones_like(xm), np.zeros_like(xm), 1.0
    if cp.site["form"] == "smooth_gradient":
        a = cp.site["angle_rad"]
        return np.exp(cp.site["log_gradient_per_m"] * (X * math.cos(a) + Y * math.sin(a))), \
            np.zeros_like(xm), 1.0
    sx, sy = SITES[cp.site["site"]]
    Rr = cp.site["radius_m"]
    g = cp.site["gain"] * np.exp(-((X - sx) ** 2 + (Y - sy) ** 2) / (2 * Rr * Rr))
    return np.ones_like(xm), g, cp.site["depth_scale_m"]


def lateral_path(rc, t, S):
    P = rc["params"]
    px, py = rc["press_xy"]
    if rc["kind"] not in ("force_slide", "pos_slide"):
        return np.full_like(t, px), np.full_like(t, py)
    L, ang = P["path_len_m"], P["path_angle_rad"]
    ux, uy = math.cos(ang), math.sin(ang)
    t0, t1 = P["t_lateral"]
    leg = 1.875 * L / P["speed_m_per_s"]
    s = quintic(-L / 2, L / 2, leg, t - t0)
    if P["there_and_back"]:
        tb = t0 + leg + 0.3
        back = t >= tb
        s[back] = quintic(L / 2, -L / 2, leg, t[back] - tb)
    s[t < t0] = -L / 2
    return px + ux * s, py + uy * s


def position_cmd_z(rc, t, S, xm, ym):
    P = rc["params"]; k = rc["kind"]
    if k in ("press_ramp", "staircase", "indent_series"):
        return waypoints_traj(P["wps"], t)
    if k in ("chirp", "palpation"):
        z = waypoints_traj(P["wps"], t)
        tc0, tc1 = P["t_osc"]
        m = (t >= tc0) & (t <= tc1)
        tt = t[m] - tc0; T = tc1 - tc0
        taper = np.clip(np.minimum(tt, T - tt) / 0.5, 0, 1)
        if k == "chirp":
            f0, f1 = P["f0_hz"], P["f1_hz"]
            if P["sweep"] == "exponential":
                kk = math.log(f1 / f0) / T
                phase = 2 * math.pi * f0 * (np.exp(kk * tt) - 1) / kk
                fi = f0 * np.exp(kk * tt)
            else:
                phase = 2 * math.pi * (f0 * tt + (f1 - f0) * tt ** 2 / (2 * T))
                fi = f0 + (f1 - f0) * tt / T
            amp = np.minimum(P["amp_m"], P["robot_accel_limit_m_per_s2"] / (2 * math.pi * fi) ** 2)
            z[m] -= amp * taper * np.sin(phase)
        else:
            f0, f1 = P["f_hz"]
            osc = np.sin(2 * math.pi * f0 * tt) + P["amp_ratio_second_tone"] * np.sin(
                2 * math.pi * f1 * tt + P["phase2"])
            z[m] -= P["amp_m"] * taper * osc + P["depth_trend_m"] * tt / T
        return z
    # pos_slide: follow the lab's surface model at the commanded depth
    hov, d = P["hover_m"], P["depth_cmd_m"]
    zs = est_surface(S, xm, ym)
    ta, tb = P["t_down"]; tu0, tu1 = P["t_up"]
    off = np.full_like(t, hov)
    m = t >= ta
    off[m] = quintic(hov, -d, tb - ta, t[m] - ta)
    m = t >= tu0
    off[m] = quintic(-d, hov, tu1 - tu0, t[m] - tu0)
    return zs + off


def simulate(S, case_effects):
    """Simulate every case (list of {name: params}) on the session's recordings, all cases
    vectorised together. Returns per case: list of per-recording output dicts, and stats."""
    C = len(case_effects)
    cps = [CaseParams(S, e) for e in case_effects]
    ar = np.arange(C)
    body, robot = S["body"], S["robot"]
    c_lin = body["c_lin_ns_per_m"]; sig0 = body["bristle_sigma0_per_m"]
    k_arm, tau_arm = robot["k_arm_n_per_m"], robot["tau_arm_s"]
    m_res = robot["residual_probe_mass_kg"]
    rr = np.array([cp.r for cp in cps]); tt = np.array([cp.tau for cp in cps])
    nbu = max(1, int((rr > 0).any(0).nonzero()[0].max() + 1) if (rr > 0).any() else 1)
    rr = rr[:, :nbu]; tt = tt[:, :nbu]
    alpha = np.exp(-DT / tt); beta = rr * np.exp(-DT / (2 * tt)); Rsum = rr.sum(1)
    m_t = np.array([cp.m_t for cp in cps]); w_t = np.array([cp.w_t for cp in cps])
    z_t = np.array([cp.z_t for cp in cps])
    mu_c = np.array([cp.mu_c for cp in cps]); mu_s = np.array([cp.mu_s for cp in cps])
    vs = np.array([cp.vs for cp in cps]); bvis = np.array([cp.b for cp in cps])
    fc = np.array([cp.filt for cp in cps])
    fb0, fb1, fb2, fa1, fa2 = (fc[:, k][:, None] for k in range(5))
    Wma = fc[:, 5].astype(int)
    lat = np.array([cp.lat for cp in cps]); mz = np.array([cp.m_zoh for cp in cps])
    ph = np.array([cp.ph for cp in cps])
    c_hc = np.array([cp.c_hc for cp in cps]); p_hc = np.array([cp.p_hc for cp in cps])
    any_hc = bool(np.any(c_hc > 0))
    br_flag = np.array([1.0 if cp.breath else 0.0 for cp in cps])
    bp = next((cp.breath for cp in cps if cp.breath), None)
    out = [[] for _ in range(C)]
    stats = [{"max_delta_by_rec": []} for _ in range(C)]
    site_state = {}   # site -> (u, E, h, last session time) body memory per site

    for rc in S["recordings"]:
        D = rc["duration_s"]; N = int(math.ceil(D / DT)) + 1
        t = np.arange(N) * DT
        T0 = rc["session_start_s"]
        xc, yc = lateral_path(rc, t, S)
        sv = robot["servo_hz"], robot["servo_zeta"]
        xm, vxm, axm = track2(xc, *sv)
        ym, vym, aym = track2(yc, *sv)
        s0, gx, gy = surface(S["geom"], xm, ym)
        nvec = normal_from_grad(gx, gy)
        nz = nvec[:, 2]
        u_tab, w_tab, u_touch = contact_table(S, rc)
        Ftab = np.array([elastic_from_w(S, w_tab, cp.nl) for cp in cps])   # (C, J)
        dFtab = np.diff(Ftab, axis=1, append=Ftab[:, -1:]) / DU
        Jmax = Ftab.shape[1] - 2
        u0 = u_tab[0]
        Sxy = np.empty((N, C)); Gi = np.empty((N, C)); dci = np.empty(C)
        for c, cp in enumerate(cps):
            Sxy[:, c], Gi[:, c], dci[c] = site_factors(cp, S, xm, ym)
        any_inc = bool(np.any(Gi > 0))
        # breathing (session clock)
        if bp is not None:
            zb_u, zbd_u = breath_unit(bp, T0 + t)
            cxy = S["geom"]["center_xy"]
            X, Y = xm - cxy[0], ym - cxy[1]
            rho2 = ((X / 0.06) ** 2 + (Y / 0.08) ** 2) / 2
            Ash = bp["A_center_m"] * (1 - (1 - bp["edge_ratio"]) * rho2)
            zb = Ash * zb_u; zbd = Ash * zbd_u
            vsk = np.stack([bp["lateral_ratio"] * X / 0.08 * zbd,
                            bp["lateral_ratio"] * Y / 0.08 * zbd + bp["craniocaudal_ratio"] * zbd,
                            np.zeros(N)], 1)
        else:
            zb = np.zeros(N); vsk = np.zeros((N, 3))
        force = rc["mode"] == "force"
        if not force:
            zcmd = position_cmd_z(rc, t, S, xm, ym)
            zm_pre, vzm_pre, azm_pre = track2(zcmd, *sv)
        # state
        st = site_state.get(rc["site"])
        u_snap = u_tab[N_PRE]
        u = np.full(C, u_snap); E = np.zeros(C); h = np.zeros((C, nbu))
        if st is not None:
            u, E, h = decay_free(st, T0 - st[3], alpha, beta, rr, Rsum, u_snap, Ftab, u0)
        hs = h.sum(1)
        darm = np.zeros(C); Fz_prev = np.zeros(C)
        xt_pos = np.zeros(C); xt_vel = np.zeros(C); tis_init = np.zeros(C, bool)
        zbr = np.zeros((C, 3))
        s1 = np.zeros((C, 3)); s2 = np.zeros((C, 3))
        hist = np.zeros((N, C, 3))
        cs = np.zeros((N + 1, C, 3)) if np.any(Wma > 1) else None
        maxd = np.zeros(C)
        zm_hist = np.empty((N, C)); vz_hist = np.empty((N, C))
        bias_w = np.array([case_bias_world(cp, rc) for cp in cps])   # (C,3)
        grav = np.array(rc["grav_residual_n"])
        if force:
            P = rc["params"]; ctl = rc["ctrl"]
            tick = int(round(2000.0 / ctl["rate_hz"]))
            Ka = 2 * math.pi * ctl["bandwidth_hz"] / ctl["assumed_stiffness_n_per_m"]
            a_lpf = 1 - math.exp(-2 * math.pi * ctl["force_lpf_hz"] * DT * tick)
            zc_c = np.full(C, P["z_start"]); zm_c = np.full(C, P["z_start"]); vm_c = np.zeros(C)
            phase = np.zeros(C, int); t_sw = np.full(C, np.inf); fzf = np.zeros(C)
            vcmd = np.zeros(C)
            w2s = (2 * math.pi * sv[0]) ** 2; c2s = 2 * sv[1] * 2 * math.pi * sv[0]
            drift_tick = np.zeros((N // tick + 2, C))
            tk_times = T0 + np.arange(N // tick + 2) * tick * DT
            for c, cp in enumerate(cps):
                if cp.drift:
                    drift_tick[:, c] = drift_fn(cp.drift, tk_times)
            cnoise = rc["_cnoise"]
        idx_c = np.arange(C)
        any_tis = bool(np.any(m_t > 0)); any_br = bp is not None and bool(br_flag.any())
        any_filt = bool(np.any(fc[:, :5] != np.array([1.0, 0, 0, 0, 0])))
        any_ma = cs is not None
        ma_lane = (Wma > 1)[:, None]
        strib = bool(np.any(mu_s != mu_c))
        s0l = s0.tolist(); nzl = nz.tolist()
        vxl = vxm.tolist(); vyl = vym.tolist(); axl = axm.tolist(); ayl = aym.tolist()
        zbl = zb.tolist(); vskl = vsk.tolist()
        if not force:
            zml = zm_pre.tolist(); vzl = vzm_pre.tolist(); azl = azm_pre.tolist()
        ktan = np.zeros(C)
        settled = False
        V = np.zeros((C, 3)); F = np.zeros((C, 3))
        ca = DT / tau_arm; ika = 1.0 / k_arm
        for n in range(N):
            # --- robot z
            if force:
                if n % tick == 0:
                    k = n // tick
                    nn = n - 1
                    if nn >= 0:
                        idx = np.minimum(np.maximum(((nn - ph) // mz) * mz + ph - lat, 0), nn)
                        fm = hist[idx, idx_c, 2] + bias_w[:, 2] + grav[2] + drift_tick[k] + cnoise[k]
                    else:
                        fm = bias_w[:, 2] + grav[2] + drift_tick[0]
                    fzf = fzf + a_lpf * (fm - fzf)
                    tn = n * DT
                    go = (phase == 0) & (tn >= P["t_start_approach"]) & (fzf > ctl["F_contact_n"])
                    t_sw = np.where(go, tn, t_sw); phase = np.where(go, 1, phase)
                    if tn >= P["T_release_s"]:
                        phase = np.where(phase <= 1, 2, phase)
                    if tn >= P["T_release_s"] + P["T_down_s"]:
                        phase = np.where(phase == 2, 3, phase)
                    Fc = ctl["F_contact_n"]
                    ramp = np.minimum(np.maximum((tn - t_sw) / P["T_ramp_s"], 0.0), 1.0)
                    tgt = Fc + (P["F_target_n"] - Fc) * ramp
                    if phase.max() >= 2:
                        down = min(max((tn - P["T_release_s"]) / P["T_down_s"], 0.0), 1.0)
                        tgt = np.where(phase >= 2, P["F_target_n"] * (1 - down), tgt)
                    vctl = np.minimum(np.maximum(-Ka * (tgt - fzf), -ctl["v_max"]), ctl["v_max"])
                    vcmd = np.where(phase == 0, -P["v_approach"] if tn >= P["t_start_approach"] else 0.0,
                                    np.where(phase == 3, np.where(zc_c < P["z_start"] + 0.005, P["v_retract"], 0.0), vctl))
                zc_c = zc_c + vcmd * DT
                acc_m = w2s * (zc_c - zm_c) - c2s * vm_c
                vm_c = vm_c + acc_m * DT
                zm_c = zm_c + vm_c * DT
                zm = zm_c; vzm = vm_c; azm = acc_m
                zm_hist[n] = zm; vz_hist[n] = vzm
            else:
                zm = zml[n]; vzm = vzl[n]; azm = azl[n]
            # --- arm compliance (the true tip sits above the logged one by ~F/k_arm)
            ddarm = ca * (Fz_prev * ika - darm)
            darm = darm + ddarm
            zt = zm + darm
            # --- geometric indentation at the face centre
            if any_br:
                d = (s0l[n] + br_flag * zbl[n] - zt) * nzl[n]
            else:
                d = (s0l[n] - zt) * nzl[n]
            if settled:
                if not (d >= u_snap).any():
                    # free air, body at rest: only the residual probe inertia reaches the sensor
                    F[:, 0] = -m_res * axl[n]; F[:, 1] = -m_res * ayl[n]; F[:, 2] = -m_res * azm
                    Fz_prev = F[:, 2]
                    if any_filt:
                        y = fb0 * F + s1
                        s1 = fb1 * F - fa1 * y + s2
                        s2 = fb2 * F - fa2 * y
                    else:
                        y = F
                    if any_ma:
                        cs[n + 1] = cs[n] + y
                        y = np.where(ma_lane, (cs[n + 1] - cs[np.maximum(n + 1 - Wma, 0), idx_c]) / Wma[:, None], y)
                    hist[n] = y
                    continue
                settled = False
            # free-surface prediction (QLV + damper, semi-implicit)
            if any_hc:
                cu = c_lin + c_hc * np.maximum(u - u_touch, 0.0) ** p_hc
            else:
                cu = c_lin
            uf = u - DT * (E + hs) / (cu + DT * ktan * (1 + Rsum))
            contact = d >= uf
            un = np.where(contact, d, uf)
            x = (un - u0) * (1.0 / DU)
            j = x.astype(int)
            np.minimum(j, Jmax, out=j); np.maximum(j, 0, out=j)
            F0 = Ftab[ar, j]; F1 = Ftab[ar, j + 1]
            fr = x - j
            Fe = F0 + (F1 - F0) * fr
            Sfac = Sxy[n]
            dn = un - u_touch
            if any_inc:
                Sfac = Sfac * (1 + Gi[n] * (1 - np.exp(-np.maximum(dn, 0.0) / dci)))
            ktan = Sfac * (F1 - F0) * (1.0 / DU)
            En = Sfac * Fe
            dE = En - E
            h = h * alpha + dE[:, None] * beta
            hs = h.sum(1)
            ud = (un - u) * (1.0 / DT)
            u = un; E = En
            if any_hc:
                cu = c_lin + c_hc * np.maximum(dn, 0.0) ** p_hc
            Fn = E + hs + cu * ud
            vprobe_z = vzm + ddarm * (1.0 / DT)
            if any_tis:
                # tissue mass on a stiff coupling to the probe (only in contact)
                xt_pos = np.where(tis_init, xt_pos, zt); xt_vel = np.where(tis_init, xt_vel, vprobe_z)
                a_t = w_t * w_t * (zt - xt_pos) + 2 * z_t * w_t * (vprobe_z - xt_vel)
                xt_vel = xt_vel + a_t * DT; xt_pos = xt_pos + xt_vel * DT
                tis_init = contact
                Fn = Fn - m_t * a_t * nzl[n]
            Fn = np.where(contact, np.maximum(Fn, 0.0), 0.0)
            np.maximum(maxd, np.where(contact, dn, 0.0), out=maxd)
            # --- friction: LuGre bristle in the tangent plane
            nv = nvec[n]
            if any_br:
                V[:, 0] = vxl[n] - br_flag * vskl[n][0]; V[:, 1] = vyl[n] - br_flag * vskl[n][1]
            else:
                V[:, 0] = vxl[n]; V[:, 1] = vyl[n]
            V[:, 2] = vprobe_z
            vn = V @ nv
            Vt = V - vn[:, None] * nv
            sp = np.sqrt((Vt * Vt).sum(1)) + 1e-12
            mu = mu_c + (mu_s - mu_c) * np.exp(-(sp / vs) ** 2) if strib else mu_c
            dec = np.exp(-sig0 * DT * sp / mu)
            zss = Vt * (mu / (sig0 * sp))[:, None]
            zbr = zss + (zbr - zss) * dec[:, None]
            cf = contact.astype(float)
            zbr *= cf[:, None]
            F = np.multiply.outer(Fn, nv) - (Fn * sig0)[:, None] * zbr - (cf * bvis)[:, None] * Vt
            F[:, 0] -= m_res * axl[n]; F[:, 1] -= m_res * ayl[n]; F[:, 2] -= m_res * azm
            Fz_prev = F[:, 2]
            # a free surface back at rest snaps exactly to rest (per lane, so that a lane's
            # result never depends on which other lanes share the batch)
            rest = ~contact & (np.abs(E) < 1e-7) & (np.abs(hs) < 1e-7)
            if rest.any():
                u = np.where(rest, u_snap, u); E = np.where(rest, 0.0, E)
                h = np.where(rest[:, None], 0.0, h); hs = np.where(rest, 0.0, hs)
                if rest.all():
                    settled = True
            # --- sensor electronics: biquad then moving average
            if any_filt:
                y = fb0 * F + s1
                s1 = fb1 * F - fa1 * y + s2
                s2 = fb2 * F - fa2 * y
            else:
                y = F
            if any_ma:
                cs[n + 1] = cs[n] + y
                y = np.where(ma_lane, (cs[n + 1] - cs[np.maximum(n + 1 - Wma, 0), idx_c]) / Wma[:, None], y)
            hist[n] = y
        if not force:
            zm_hist[:] = zm_pre[:, None]; vz_hist[:] = vzm_pre[:, None]
        site_state[rc["site"]] = (u.copy(), E.copy(), h.copy(), T0 + D)
        # --- sampling at the logger's acquisition instants
        tacq = rc["_tacq"]
        gi = np.arange(N)
        idx = np.clip(((gi[:, None] - ph) // mz) * mz + ph - lat, 0, N - 1)   # (N, C)
        sens = hist[idx, idx_c[None, :], :]   # (N, C, 3)
        pos = tacq / DT
        i0 = np.clip(pos.astype(int), 0, N - 2); f0 = (pos - i0)[:, None]
        noise = rc["_fnoise"]
        q = S["noise"]["quantum_n"]
        tsess = T0 + tacq
        lever = -S["probe"]["sensor_lever_m"] * np.array(rc["probe_axis"])
        tcp = np.array(robot["tcp_offset_m"])
        for c, cp in enumerate(cps):
            f = sens[i0, c] * (1 - f0[:, :]) + sens[i0 + 1, c] * f0
            f = f + bias_w[c] + grav
            if cp.drift:
                dz = drift_fn(cp.drift, tsess)
                fx_, fy_ = cp.drift["xy_fraction"]
                f = f + np.stack([fx_ * dz, fy_ * dz, dz], 1)
            f = np.round((f + noise) / q) * q
            pz = zm_hist[i0, c] * (1 - f0[:, 0]) + zm_hist[i0 + 1, c] * f0[:, 0]
            px = xm[i0] * (1 - f0[:, 0]) + xm[i0 + 1] * f0[:, 0]
            py = ym[i0] * (1 - f0[:, 0]) + ym[i0 + 1] * f0[:, 0]
            p = np.stack([px, py, pz], 1) + tcp + rc["_pnoise"]
            p = np.round(p / robot["encoder_quantum_m"]) * robot["encoder_quantum_m"]
            o = {"t": rc["_stamps"], "p": p, "f": f}
            if rc["columns_velocity"]:
                vzs = vz_hist[i0, c] * (1 - f0[:, 0]) + vz_hist[i0 + 1, c] * f0[:, 0]
                o["v"] = np.stack([vxm[i0], vym[i0], vzs], 1) + rc["_vnoise"]
            if rc["columns_torque"]:
                o["tq"] = np.cross(lever[None, :], f) + rc["_tqnoise"]
            out[c].append(o)
            stats[c]["max_delta_by_rec"].append(float(maxd[c]))
        stats_tables = (u_tab, w_tab, u_touch)
        for c in range(C):
            stats[c].setdefault("tables", []).append(stats_tables)
    return out, stats


def decay_free(st, gap_s, alpha, beta, rr, Rsum, u_snap, Ftab, u0):
    """Advance a site's body memory through free air (probe elsewhere) for gap_s seconds:
    E(1+R)' = Σh/τ, h' = −h/τ + r·E' on a 5 ms grid (damper neglected)."""
    u, E, h = (a.copy() for a in st[:3])
    if gap_s <= 0:
        return u, E, h
    tau = -DT / np.log(alpha)
    dt = 5e-3
    steps = int(min(gap_s, 120.0) / dt)
    for _ in range(steps):
        dE = dt * (h / tau).sum(1) / (1 + Rsum)
        E = np.maximum(E + dE, 0.0)
        h = h * np.exp(-dt / tau) + rr * dE[:, None]
    # back to u by inverting the (case-wise) elastic table
    for c in range(len(u)):
        u[c] = np.interp(E[c], Ftab[c], u0 + np.arange(Ftab.shape[1]) * DU) if E[c] > 0 else u_snap
    return u, E, h


# ----------------------------------------------------------------------------- truth

def effect_truth(name, p, S, stats_case, cp):
    recs = S["recordings"]
    t_first = min(rc["session_start_s"] + rc["_tacq"][0] for rc in recs)
    t_last = max(rc["session_start_s"] + rc["_tacq"][-1] for rc in recs)
    if name == "sensor_bias":
        bs = np.array([case_bias_world(cp, rc) for rc in recs])
        n = np.array([rc["sampling"]["n"] for rc in recs], float)
        b = (bs * n[:, None]).sum(0) / n.sum()
        return {"fz_n": b[2], "bias_n": b.tolist()}, {"per_recording_world_n": bs.tolist()}
    if name == "sensor_delay":
        lat0 = S["robot"]["transport_latency_s"]
        zoh = (0.5 / p["internal_rate_hz"]) if p["internal_rate_hz"] else 0.0
        return {"delay_s": lat0 + p["latency_s"] + zoh}, {
            "latency_s": p["latency_s"], "nuisance_transport_latency_s": lat0,
            "zoh_mean_delay_s": zoh,
            "note": "delay_s = effect latency + nuisance latency + half the ZOH period"}
    if name == "tissue_inertia":
        return {"moving_mass": p["moving_mass_kg"]}, {}
    if name == "nonlinear_stiffness":
        return exponent_truth(S, stats_case, cp)
    if name == "viscoelastic_relaxation":
        taus, rs = np.array(p["taus_s"]), np.array(p["ratios"])
        tr = {"tau_s": float((rs * taus).sum() / rs.sum()), "ratio": float(rs.sum())}
        if p["form"] != "box_spectrum":
            tr["branches"] = len(taus)
        fast = taus < 2.0
        tr["fast_ratio"] = float(rs[fast].sum()); tr["slow_ratio"] = float(rs[~fast].sum())
        tr["fast_tau_s"] = float((rs[fast] * taus[fast]).sum() / max(rs[fast].sum(), 1e-12))
        tr["slow_tau_s"] = float((rs[~fast] * taus[~fast]).sum() / max(rs[~fast].sum(), 1e-12))
        return tr, {"grouping": "fast = branches with τ < 2 s", "continuous": p["form"] == "box_spectrum"}
    if name == "breathing_motion":
        A = p["typical_half_p2p_m"]
        cx, cy = S["geom"]["center_xy"]
        at_sites = {s: A * (1 - (1 - p["edge_ratio"]) * ((ox / 0.06) ** 2 + (oy / 0.08) ** 2) / 2)
                    for s, (ox, oy) in SITES.items()}
        return {"freq_hz": p["mean_rate_hz"], "amplitude_m": A, "rise_m": 2 * A,
                "inhale_share": p["inhale_share"], "pause_share": p["pause_share"],
                "edge_rise": p["edge_ratio"], "amplitude_at_sites_m": at_sites}, {
            "edge_rise_definition": "amplitude at the four corner sites over the centre's"}
    if name == "site_heterogeneity":
        return site_truth(S, stats_case, cp, p)
    if name == "sliding_friction":
        return {"mu": p["mu_c"], "viscous_ns_per_m": S["body"]["b0_ns_per_m"] + p["b_ns_per_m"]}, {
            "mu_static": p["mu_s"], "baseline_mu0": S["body"]["mu0"],
            "baseline_b0_ns_per_m": S["body"]["b0_ns_per_m"],
            "mu_beyond_baseline": p["mu_c"] - S["body"]["mu0"],
            "bristle_sigma0_per_m": S["body"]["bristle_sigma0_per_m"],
            "note": "mu and viscous_ns_per_m are totals (baseline included)"}
    if name == "sensor_filter":
        return {"cutoff_hz": filter_cutoff(p)}, {
            "order": {"butterworth2": 2, "one_pole": 1, "two_equal_poles": 2, "moving_average": "FIR"}[p["form"]]}
    if name == "bias_drift":
        d0, d1 = drift_fn(p, np.array([t_first, t_last]))
        eps = 1e-3
        rate = (drift_fn(p, np.array([t_first + eps])) - drift_fn(p, np.array([t_first]))) / eps
        tr = {"fz_n": float(d0), "total_n": float(d1 - d0), "rate_n_per_s": float(rate[0]),
              "settle_s": p.get("settle_s", 0.0)}
        return tr, {"session_first_sample_s": t_first, "session_last_sample_s": t_last,
                    "clock": "session clock (session_time_s + t − t_first_of_file)"}
    if name == "depth_dependent_damping":
        return {"ratio_at_10mm": p["ratio_at_10mm"], "exponent": p["exponent"]}, {
            "c_lin_ns_per_m": S["body"]["c_lin_ns_per_m"]}
    return {}, {}


def representative_law(S, stats_case, cp, protos=("press",)):
    recs = S["recordings"]
    sel = [i for i, rc in enumerate(recs) if rc["protocol"] in protos]
    deepest = max(stats_case["max_delta_by_rec"][i] for i in sel)
    u_tab, w_tab, ut = stats_case["tables"][sel[0]]
    d = u_tab - ut
    return d, w_tab, deepest


def exponent_truth(S, stats_case, cp):
    """Effective log–log slope of the elastic law over 2 mm … the deepest press, the
    indentation being the face-mean indentation w (origin: where the full-contact law
    extrapolates to zero force); the same slope measured from the skin height on the
    probe axis and from first touch are given as details."""
    d, w, deepest = representative_law(S, stats_case, cp)
    F = elastic_from_w(S, w, cp.nl)
    F0 = elastic_from_w(S, w, None)
    w_deep = float(np.interp(deepest, d, w))
    sl, two = loglog_slope(w, F, w_deep)
    sl0, _ = loglog_slope(w, F0, w_deep)
    u_axis = d + stats_case["tables"][0][2]   # indentation at the probe axis
    sl_axis, _ = loglog_slope(u_axis, F, deepest + stats_case["tables"][0][2])
    sl_touch, _ = loglog_slope(d, F, deepest)
    sle, _ = loglog_slope(w, nonlin_N(cp.nl, w), w_deep)
    return {"exponent": sl}, {
        "deepest_press_m": w_deep, "deepest_press_from_first_touch_m": deepest,
        "exponent_two_point": two, "exponent_of_none_body_same_range": sl0,
        "exponent_of_effect_law_alone": sle,
        "exponent_from_skin_at_probe_axis": sl_axis, "exponent_from_first_touch": sl_touch,
        "indentation_origin": "face-mean indentation w (full-contact law extrapolated to zero)",
        "fit": "least-squares log–log slope on 40 log-spaced depths, 2 mm … deepest press"}


def site_truth(S, stats_case, cp, p):
    recs = S["recordings"]
    cx, cy = S["geom"]["center_xy"]
    by, detail = {}, {}
    for s, (ox, oy) in SITES.items():
        Sxy, Gi, dc = site_factors(cp, S, np.array([cx + ox]), np.array([cy + oy]))
        deep = [stats_case["max_delta_by_rec"][i] for i, rc in enumerate(recs) if rc["site"] == s]
        dmax = max(deep) if deep else 0.008
        dd = np.linspace(0.002, max(dmax, 0.0025), 50)
        fac = Sxy[0] * (1 + Gi[0] * (1 - np.exp(-dd / dc)))
        val = float(fac.mean())
        detail[s] = {"at_2mm": float(fac[0]), "at_deepest": float(fac[-1]), "deepest_m": dmax,
                     "visited": bool(deep)}
        if deep:
            by[s] = val
    return {"stiffness_by_site": by}, {"all_sites": detail,
                                       "definition": "mean stiffness scale over 2 mm … deepest press at the site"}


def nuisance_truth(S, stats_none):
    recs = []
    for i, rc in enumerate(S["recordings"]):
        e = {k: v for k, v in rc.items() if not k.startswith("_")}
        e["params"] = {k: v for k, v in rc["params"].items()}
        e["true_surface_z_at_press_xy"] = float(surface(S["geom"], *rc["press_xy"])[0])
        e["face_first_touch_u_m"] = stats_none["tables"][i][2] if stats_none else None
        e["max_indentation_none_m"] = stats_none["max_delta_by_rec"][i] if stats_none else None
        recs.append(e)
    nz = dict(S["noise"])
    return {
        "geometry": S["geom"], "true_site_surface_z": S["true_site_z"],
        "lab_surface_estimate": S["surface_estimate"], "dataset_meta": S["dataset_meta"],
        "body_law": S["body"], "probe": S["probe"], "robot_and_sensor": S["robot"],
        "noise": nz, "logger": S["logger"], "recordings": recs,
        "integration_step_s": DT,
    }


# ----------------------------------------------------------------------------- writing

def write_case(S, name, effects, out_c, stats_c, cp, path, stats_none):
    ds = os.path.join(path, "dataset")
    os.makedirs(ds, exist_ok=True)
    entries = []
    for rc, o in zip(S["recordings"], out_c):
        cols = ["t", "px", "py", "pz", "fx", "fy", "fz"]
        arrs = [o["t"][:, None], o["p"], o["f"]]
        fmts = ["%.6f"] + ["%.7f"] * 3 + ["%.5f"] * 3
        if "v" in o:
            cols += ["vx", "vy", "vz"]; arrs.append(o["v"]); fmts += ["%.6f"] * 3
        if "tq" in o:
            cols += ["tx", "ty", "tz"]; arrs.append(o["tq"]); fmts += ["%.6f"] * 3
        np.savetxt(os.path.join(ds, rc["file"]), np.hstack(arrs), fmt=fmts, delimiter=",",
                   header=",".join(cols), comments="")
        e = {"file": rc["file"], "site": rc["site"], "protocol": rc["protocol"]}
        if S["logger"]["session_time_s_written"]:
            e["session_time_s"] = round(rc["session_start_s"] + rc["_tacq"][0], 6)
        entries.append(e)
    meta = {"format": "echogym-recordings/1",
            "description": "abdominal ultrasound probe: presses, palpation and sweeps on a volunteer",
            "nominal_surface_z": S["dataset_meta"]["nominal_surface_z"],
            "torso_center_xy": S["dataset_meta"]["torso_center_xy"],
            "recordings": entries}
    with open(os.path.join(ds, "dataset.json"), "w") as fh:
        json.dump(jsonable(meta), fh, indent=2)
    eff_t, eff_d = {}, {}
    for en in CATALOGUE:
        if en in effects:
            tr, det = effect_truth(en, effects[en], S, stats_c, cp)
            eff_t[en] = tr
            d = {k: v for k, v in effects[en].items()}
            d.update(det)
            eff_d[en] = d
    truth = {"generator": GENERATOR, "seed": S["seed"], "case": name,
             "effects": eff_t, "effect_details": eff_d,
             "nuisances": nuisance_truth(S, stats_none),
             "none_body_exponent": exponent_truth(S, stats_none, CaseParams(S, {}))[1]["exponent_of_none_body_same_range"] if stats_none else None}
    with open(os.path.join(path, "truth.json"), "w") as fh:
        json.dump(jsonable(truth), fh, indent=1)


def case_name(effs):
    return "+".join(e for e in CATALOGUE if e in effs) if effs else "none"


def visibility(S, out_case, out_none):
    """max(RMS Δfz / σz, RMS |Δf| / σ_vec) over every sample: the --check metric."""
    sig = np.array(S["noise"]["sigma_total_n"])
    sv = sz = 0.0; n = 0
    for a, b in zip(out_case, out_none):
        d = a["f"] - b["f"]
        sv += (d ** 2).sum(); sz += (d[:, 2] ** 2).sum(); n += len(d)
    return max(math.sqrt(sz / n) / sig[2], math.sqrt(sv / n) / math.sqrt((sig ** 2).sum()))


def boost(name, p, k):
    """Raise an effect's strength by about k (> 1) within its physical range; False at the cap."""
    if name == "sensor_bias":
        key = "world_offset_n" if "world_offset_n" in p else "sensor_frame_offset_n"
        v = np.array(p[key])
        if abs(v[2]) >= 3.5:
            return False
        k = min(k, 3.5 / abs(v[2]))
        p[key] = (v * k).tolist()
        if "mass_kg" in p:
            p["mass_kg"] *= k
    elif name == "sensor_delay":
        if p["latency_s"] >= 0.08:
            return False
        p["latency_s"] = min(p["latency_s"] * k, 0.08)
    elif name == "tissue_inertia":
        if p["moving_mass_kg"] >= 0.9:
            return False
        p["moving_mass_kg"] = min(p["moving_mass_kg"] * k, 0.9)
    elif name == "nonlinear_stiffness":
        f = p["form"]
        if f == "fung_exponential":
            if p["d0_m"] <= 0.003:
                return False
            p["d0_m"] = max(p["d0_m"] / k, 0.003)
        elif f == "power_law":
            if p["n"] >= 2.0:
                return False
            p["n"] = min(1 + (p["n"] - 1) * k, 2.0)
        elif f == "toe_linear":
            if p["toe_m"] >= 0.007:
                return False
            p["toe_m"] = min(p["toe_m"] * k, 0.007)
        else:
            if p["d1_m"] <= 0.003:
                return False
            p["d1_m"] /= k; p["d2_m"] /= k
    elif name == "viscoelastic_relaxation":
        if sum(p["ratios"]) >= 1.5:
            return False
        k = min(k, 1.5 / sum(p["ratios"]))
        p["ratios"] = [x * k for x in p["ratios"]]
    elif name == "breathing_motion":
        if p["A_center_m"] >= 0.007:
            return False
        k = min(k, 0.007 / p["A_center_m"])
        p["A_center_m"] *= k; p["typical_half_p2p_m"] *= k
    elif name == "site_heterogeneity":
        if p["form"] == "stiff_inclusion":
            if p["gain"] >= 3.0:
                return False
            p["gain"] = min(p["gain"] * k, 3.0)
        else:
            if p["log_gradient_per_m"] >= 8.0:
                return False
            p["log_gradient_per_m"] = min(p["log_gradient_per_m"] * k, 8.0)
    elif name == "sliding_friction":
        if p["mu_c"] >= 0.6 and p["b_ns_per_m"] >= 100:
            return False
        k1 = min(k, 0.6 / p["mu_c"])
        p["mu_c"] *= k1; p["mu_s"] *= k1
        p["b_ns_per_m"] = min(p["b_ns_per_m"] * k, 100.0)
    elif name == "sensor_filter":
        if "fc_hz" in p:
            if p["fc_hz"] <= 2.0:
                return False
            p["fc_hz"] = max(p["fc_hz"] / k, 2.0)
        else:
            if p["window_s"] >= 0.2:
                return False
            p["window_s"] = min(p["window_s"] * k, 0.2)
    elif name == "bias_drift":
        if p["form"] in ("linear", "linear_thermal_wobble"):
            if abs(p["rate_n_per_s"]) >= 0.008:
                return False
            p["rate_n_per_s"] *= k
            if "wobble_n" in p:
                p["wobble_n"] *= k
        else:
            if abs(p["D_inf_n"]) >= 4.0:
                return False
            p["D_inf_n"] *= k
    elif name == "depth_dependent_damping":
        if p["ratio_at_10mm"] >= 8.0:
            return False
        p["ratio_at_10mm"] = min(p["ratio_at_10mm"] * k, 8.0)
        p["c_hc"] = p["ratio_at_10mm"] * S_C_LIN[0] / 0.01 ** p["exponent"]
    p["visibility_boosts"] = p.get("visibility_boosts", 0) + 1
    p["visibility_boost_factor"] = p.get("visibility_boost_factor", 1.0) * k
    return True


S_C_LIN = [None]


def run_cases(seed, case_list, out_dir, nested):
    """case_list: list of effect-name tuples (possibly empty).  Every effect involved is
    also simulated alone beside the none case: an effect under VIS_TARGET σ alone is
    strengthened (within its physical range) and everything using it re-simulated, so an
    effect has the same parameters alone and in any pair."""
    S = draw_session(seed)
    S_C_LIN[0] = S["body"]["c_lin_ns_per_m"]
    needed = sorted({e for cs in case_list for e in cs}, key=CATALOGUE.index)
    params = {e: draw_effect(e, seed, S) for e in needed}
    lanes = [tuple()] + [(e,) for e in needed]
    lanes += [cs for cs in case_list if len(cs) > 1 and cs not in lanes]
    effs = lambda ln: {e: params[e] for e in ln}
    out, stats = simulate(S, [effs(ln) for ln in lanes])
    for rnd in range(6):
        weak = []
        for k, ln in enumerate(lanes):
            if len(ln) == 1:
                v = visibility(S, out[k], out[0])
                params[ln[0]]["visibility_sigma"] = v
                if v < VIS_TARGET and boost(ln[0], params[ln[0]],
                                            float(np.clip(1.1 * VIS_TARGET / max(v, 1e-3), 1.15, 2.5))):
                    weak.append(ln[0])
        if not weak:
            break
        redo = [k for k, ln in enumerate(lanes) if set(ln) & set(weak)]
        o2, s2 = simulate(S, [effs(lanes[k]) for k in redo])
        for j, k in enumerate(redo):
            out[k], stats[k] = o2[j], s2[j]
    written = []
    for k, ln in enumerate(lanes):
        if ln not in case_list:
            continue
        nm = case_name(ln)
        path = os.path.join(out_dir, f"{nm}-s{seed}") if nested else out_dir
        write_case(S, nm, effs(ln), out[k], stats[k], CaseParams(S, effs(ln)), path, stats[0])
        written.append(path)
    return written


def matrix_cases(seed):
    r = rng_for(seed, 7)
    pairs = [p for p in itertools.combinations(CATALOGUE, 2)
             if set(p) != {"sensor_bias", "bias_drift"}]
    pick = r.choice(len(pairs), 4, replace=False)
    return [tuple()] + [(e,) for e in CATALOGUE] + [pairs[i] for i in sorted(pick)]


# ----------------------------------------------------------------------------- check

def read_dataset(ds):
    """Validate like server/src/recordings (dataset.rs, recording.rs); return problems and
    the files' arrays."""
    probs, data = [], {}
    mp = os.path.join(ds, "dataset.json")
    try:
        meta = json.load(open(mp))
    except Exception as e:   # noqa: BLE001
        return [f"{mp}: {e}"], data, None
    if meta.get("format") != "echogym-recordings/1":
        probs.append(f"{mp}: unknown format {meta.get('format')!r}")
    nsz = meta.get("nominal_surface_z"); tc = meta.get("torso_center_xy")
    if not isinstance(nsz, (int, float)) or not math.isfinite(nsz):
        probs.append(f"{mp}: nominal_surface_z must be a finite number")
    if not (isinstance(tc, list) and len(tc) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in tc)):
        probs.append(f"{mp}: torso_center_xy must be two finite numbers")
    if not isinstance(meta.get("description", ""), str):
        probs.append(f"{mp}: description must be a string")
    recs = meta.get("recordings")
    if not isinstance(recs, list):
        return probs + [f"{mp}: recordings missing"], data, meta
    for e in recs:
        for k in ("file", "site", "protocol"):
            if not isinstance(e.get(k), str):
                probs.append(f"{mp}: entry {e} lacks string `{k}`")
        if "session_time_s" in e and not isinstance(e["session_time_s"], (int, float)):
            probs.append(f"{mp}: session_time_s not a number in {e.get('file')}")
        fp = os.path.join(ds, e.get("file", ""))
        if not os.path.isfile(fp):
            probs.append(f"{fp}: listed in dataset.json but absent"); continue
        with open(fp) as fh:
            header = [h.strip() for h in fh.readline().split(",")]
        for col in ("t", "px", "py", "pz", "fx", "fy", "fz"):
            if col not in header:
                probs.append(f"{fp}: missing column `{col}`")
        try:
            arr = np.loadtxt(fp, delimiter=",", skiprows=1, ndmin=2)
        except Exception as ex:   # noqa: BLE001
            probs.append(f"{fp}: unparsable ({ex})"); continue
        if arr.shape[1] != len(header):
            probs.append(f"{fp}: {arr.shape[1]} columns vs header {len(header)}")
        if not np.all(np.isfinite(arr)):
            probs.append(f"{fp}: non-finite value")
        t = arr[:, header.index("t")]
        if len(t) < MIN_SAMPLES:
            probs.append(f"{fp}: only {len(t)} samples"); continue
        dtt = np.diff(t)
        if np.any(dtt <= 0):
            probs.append(f"{fp}, row {int(np.argmax(dtt <= 0)) + 3}: time does not increase")
            continue
        med = np.sort(dtt)[len(dtt) // 2]
        rate = 1 / med
        if rate < RATE_RANGE[0] * 0.99 or rate > RATE_RANGE[1] * 1.01:
            probs.append(f"{fp}: median rate {rate:.1f} Hz outside 50–2000")
        thr = max(GAP_FACTOR * med, GAP_MIN_S)
        cuts = np.flatnonzero(dtt > thr)
        bounds = np.concatenate([[0], cuts + 1, [len(t)]])
        segs = np.diff(bounds)
        if np.all(segs < MIN_SAMPLES):
            probs.append(f"{fp}: every segment under {MIN_SAMPLES} samples")
        elif np.any(segs < MIN_SAMPLES):
            probs.append(f"{fp}: (warning only) a segment under {MIN_SAMPLES} samples would be dropped")
        data[e["file"]] = {"header": header, "arr": arr, "segments": len(segs), "entry": e}
    return probs, data, meta


def classify(arr, header, surface_z):
    """docs/data.md step 9 on a file, contact from fz (0.5 N above the free-air level)."""
    fz = arr[:, header.index("fz")]
    tt = arr[:, header.index("t")]
    rate = 1.0 / np.median(np.diff(tt))
    base = np.median(fz[fz <= np.percentile(fz, 10) + 1.0])
    c = fz > base + 0.5
    if not c.any():
        return "no-contact"
    i = np.flatnonzero(c)
    seg = np.split(i, np.flatnonzero(np.diff(i) > 1) + 1)
    px, py, pz = (arr[:, header.index(k)] for k in ("px", "py", "pz"))
    best = "press"
    for sg in seg:
        if len(sg) < 5:
            continue
        dxy = np.hypot(px[sg] - px[sg[0]], py[sg] - py[sg[0]]).max()
        if dxy >= 0.02:
            return "slide"
        z = pz[sg]
        step = max(1, len(z) // max(1, int(len(z) * 100 / rate)))
        z = z[::step]
        rev = 0; ext = z[0]; dirn = 0; thr = 2e-4
        for v in z[1:]:
            if dirn == 0:
                if v > ext + thr:
                    dirn, ext = 1, v
                elif v < ext - thr:
                    dirn, ext = -1, v
            elif dirn == 1:
                if v > ext:
                    ext = v
                elif v < ext - thr:
                    rev += 1; dirn, ext = -1, v
            else:
                if v < ext:
                    ext = v
                elif v > ext + thr:
                    rev += 1; dirn, ext = 1, v
        if rev >= 6:
            best = "chirp"
    return best


def check(root):
    cases = []
    if os.path.isfile(os.path.join(root, "truth.json")):
        cases = [root]
    else:
        cases = sorted(os.path.join(root, d) for d in os.listdir(root)
                       if os.path.isfile(os.path.join(root, d, "truth.json")))
    bad = 0; tmp = None; cache = {}
    rows = []
    for cdir in cases:
        truth = json.load(open(os.path.join(cdir, "truth.json")))
        seed, name = truth["seed"], truth["case"]
        probs, data, meta = read_dataset(os.path.join(cdir, "dataset"))
        warn = [p for p in probs if "(warning only)" in p]
        errs = [p for p in probs if "(warning only)" not in p]
        # protocol labels vs docs/data.md step 9 (on the measured data)
        for fn, d in data.items():
            cl = classify(d["arr"], d["header"], meta["nominal_surface_z"])
            if cl != d["entry"]["protocol"]:
                warn.append(f"{fn}: labelled {d['entry']['protocol']}, step-9 rule says {cl}")
        sig = np.array(truth["nuisances"]["noise"]["sigma_total_n"])
        ref = os.path.join(os.path.dirname(cdir), f"none-s{seed}")
        if name == "none":
            rms_v = rms_z = 0.0; zs = vs_ = float("nan")
        else:
            if not os.path.isdir(ref):
                if seed not in cache:
                    tmp = tmp or tempfile.mkdtemp(prefix="h4none-")
                    cache[seed] = run_cases(seed, [tuple()], os.path.join(tmp, f"s{seed}"), False)[0]
                ref = cache[seed]
            _, dref, _ = read_dataset(os.path.join(ref, "dataset"))
            sq_v = sq_z = 0.0; n = 0
            for fn, d in data.items():
                a, b = d["arr"], dref[fn]["arr"]
                h = d["header"]
                if a.shape[0] != b.shape[0] or np.any(a[:, 0] != b[:, 0]):
                    errs.append(f"{fn}: time stamps differ from the none case")
                    continue
                fi = [h.index("fx"), h.index("fy"), h.index("fz")]
                df = a[:, fi] - b[:, fi]
                sq_v += (df ** 2).sum(); sq_z += (df[:, 2] ** 2).sum(); n += len(df)
            rms_v = math.sqrt(sq_v / max(n, 1)); rms_z = math.sqrt(sq_z / max(n, 1))
            zs = rms_z / sig[2]; vs_ = rms_v / math.sqrt((sig ** 2).sum())
            if max(zs, vs_) < VIS_FAIL:
                errs.append(f"effect under {VIS_FAIL} σ")
        tag = "OK " if not errs else "BAD"
        bad += bool(errs)
        rows.append((name, seed, max(zs, vs_) if name != "none" else None))
        print(f"{tag} {os.path.basename(cdir):58s} Δfz {rms_z:7.4f} N = {zs:6.1f} σz   "
              f"|Δf| {rms_v:7.4f} N = {vs_:6.1f} σ   files {len(data)}")
        for p in errs:
            print("     ERROR", p)
        for p in warn:
            print("     warn ", p)
    vals = [v for _, _, v in rows if v is not None]
    if vals:
        print(f"{len(rows)} cases, {bad} bad; smallest effect {min(vals):.1f} σ")
    if tmp:
        shutil.rmtree(tmp, ignore_errors=True)
    return 1 if bad else 0


# ----------------------------------------------------------------------------- main

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--effects")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--matrix", action="store_true")
    ap.add_argument("--seeds")
    ap.add_argument("--out")
    ap.add_argument("--check")
    a = ap.parse_args(argv)
    if a.check:
        return check(a.check)
    if a.matrix:
        if not (a.seeds and a.out):
            ap.error("--matrix needs --seeds and --out")
        for s in (int(x) for x in a.seeds.split(",")):
            t0 = time.time()
            run_cases(s, matrix_cases(s), a.out, True)
            print(f"seed {s}: 16 cases in {time.time() - t0:.1f} s", file=sys.stderr)
        return 0
    if a.effects is None or a.seed is None or not a.out:
        ap.error("need --effects LIST --seed N --out DIR (or --matrix / --check)")
    names = [] if a.effects.strip() == "none" else [e.strip() for e in a.effects.split(",") if e.strip()]
    for e in names:
        if e not in CATALOGUE:
            ap.error(f"unknown effect {e!r}; catalogue: {', '.join(CATALOGUE)}")
    if {"sensor_bias", "bias_drift"} <= set(names):
        print("note: sensor_bias together with bias_drift (the matrix never pairs them)", file=sys.stderr)
    cs = tuple(sorted(set(names), key=CATALOGUE.index))
    run_cases(a.seed, [cs], a.out, False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
