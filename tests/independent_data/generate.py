#!/usr/bin/env python3
"""Independent ground-truth generator for `echogym calibrate`.

Writes probe force/position recordings in the `echogym-recordings/1` format from a
body model that is deliberately NOT echogym's simulator (see README.md next to this
file): Hunt-Crossley-style contact on a curved, tilted surface, coloured sensor noise,
tilted probe, and optional catalogue effects with non-textbook model forms.

Only numpy and the standard library are used.

  generate.py --effects sensor_bias,breathing_motion --seed 3 --out DIR [--scale S]
  generate.py --effects none --seed 3 --out DIR
  generate.py --matrix --seeds 1,2,3 --out DIR [--scale S]
  generate.py --check DIR        # validate a --matrix output and print effect visibility
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import zlib

import numpy as np

FORMAT = "echogym-recordings/1"
DT = 2.5e-4  # internal integration step (s), 4 kHz
RATES = [100, 200, 250, 500, 1000]
SITES = {
    "upper_left": (-0.06, 0.08),
    "upper_right": (0.06, 0.08),
    "center": (0.0, 0.0),
    "lower_left": (-0.06, -0.08),
    "lower_right": (0.06, -0.08),
}
EFFECTS = [
    "sensor_bias",
    "sensor_delay",
    "tissue_inertia",
    "nonlinear_stiffness",
    "viscoelastic_relaxation",
    "breathing_motion",
    "site_heterogeneity",
    "sliding_friction",
    "sensor_filter",
    "bias_drift",
    "depth_dependent_damping",
]
PAIRS = [
    ("sensor_bias", "viscoelastic_relaxation"),
    ("nonlinear_stiffness", "breathing_motion"),
    ("sensor_delay", "site_heterogeneity"),
    ("sliding_friction", "bias_drift"),
    ("sensor_filter", "tissue_inertia"),
    ("depth_dependent_damping", "breathing_motion"),
]
DEPTH_FIT_RANGE = (2e-3, 15e-3)  # m, range of the reported power-law exponent fit
DELTA_REF = 8e-3  # m, nonlinear laws give the same force as the linear one here
DAMP_SMOOTH = 0.5e-3  # m, damping fades in over the first ~0.5 mm of contact
FRICTION_V0 = 1e-3  # m/s, tanh regularisation of Coulomb friction
BUMP_W = 0.025  # m, width of per-site surface bumps
STIFF_W = 0.03  # m, width of per-site stiffness patches
BREATH_W = 0.04  # m, kernel width for the breathing-amplitude map


# --------------------------------------------------------------------------- utils

def tag(x) -> int:
    return x if isinstance(x, int) else zlib.crc32(str(x).encode())


def rng_for(seed: int, *tags) -> np.random.Generator:
    """Independent random stream per purpose, so that cases with the same seed share
    geometry, trajectories and noise exactly, and an effect has the same parameters
    whether it appears alone or in a pair."""
    return np.random.default_rng([int(seed)] + [tag(t) for t in tags])


def expfilt(x: np.ndarray, a: float, b: float, y_prev: float = 0.0) -> np.ndarray:
    """y[n] = a*y[n-1] + b*x[n], vectorised blockwise (exact up to rounding)."""
    x = np.asarray(x, float)
    n = len(x)
    out = np.empty(n)
    if n == 0:
        return out
    if a <= 0.0:
        return b * x
    lam = -math.log(a)
    L = n if lam == 0 else max(1, min(n, int(300.0 / lam)))
    k = np.arange(L, dtype=float)
    ak_full = np.exp(-lam * k)
    inv_full = np.exp(lam * k)
    for s in range(0, n, L):
        xb = x[s:s + L]
        m = len(xb)
        y = ak_full[:m] * (a * y_prev + b * np.cumsum(xb * inv_full[:m]))
        out[s:s + m] = y
        y_prev = y[-1]
    return out


def fit_exponent(g) -> float:
    d = np.linspace(DEPTH_FIT_RANGE[0], DEPTH_FIT_RANGE[1], 400)
    return float(np.polyfit(np.log(d), np.log(g(d)), 1)[0])


def fung_law(delta0: float):
    a = DELTA_REF / (delta0 * math.expm1(DELTA_REF / delta0))
    return lambda u: a * delta0 * np.expm1(np.asarray(u) / delta0)


def power_law(n: float):
    return lambda u: DELTA_REF * (np.asarray(u) / DELTA_REF) ** n


# --------------------------------------------------------------------- the body

def draw_nuisances(seed: int) -> dict:
    r = rng_for(seed, "nuisance")
    nz = {
        "torso_center_xy": [round(0.5 + r.uniform(-0.03, 0.03), 4), round(r.uniform(-0.03, 0.03), 4)],
        "nominal_surface_z": round(0.905 + r.uniform(-0.01, 0.01), 4),
        "surface_offset_m": r.uniform(-3e-3, 3e-3),
        "dome_radius_x_m": r.uniform(0.3, 0.5),
        "dome_radius_y_m": r.uniform(1.0, 3.0),
        "dome_center_dxy_m": [r.uniform(-0.01, 0.01), r.uniform(-0.02, 0.02)],
        "surface_slope_xy": [r.uniform(-0.015, 0.015), r.uniform(-0.015, 0.015)],
        "site_bump_m": {s: r.uniform(-1.5e-3, 1.5e-3) for s in SITES},
        "site_bump_width_m": BUMP_W,
        "k_n_per_m": r.uniform(800.0, 2500.0),
        "c_ns_per_m": r.uniform(20.0, 60.0),
        "damping_fade_in_depth_m": DAMP_SMOOTH,
        "probe_tilt_deg": r.uniform(0.0, 2.0),
        "probe_tilt_azimuth_deg": r.uniform(0.0, 360.0),
        "force_noise_sigma_n": r.uniform(0.03, 0.15),
        "force_noise_cutoff_hz": r.uniform(20.0, 60.0),
        "force_white_sigma_n": r.uniform(0.0, 0.02),
        "tangential_noise_factor": r.uniform(0.5, 1.0),
        "encoder_sigma_m": r.uniform(20e-6, 50e-6),
        "velocity_noise_sigma_m_per_s": 2e-4,
        "placement_error_sigma_m": 1.5e-3,
        "planning_surface_error_max_m": 1e-3,
    }
    return nz


class Body:
    def __init__(self, nz: dict):
        self.nz = nz
        self.cx, self.cy = nz["torso_center_xy"]
        th = math.radians(nz["probe_tilt_deg"])
        az = math.radians(nz["probe_tilt_azimuth_deg"])
        self.nhat = np.array([math.sin(th) * math.cos(az), math.sin(th) * math.sin(az), math.cos(th)])

    def site_xy(self, site):
        ox, oy = SITES[site]
        return self.cx + ox, self.cy + oy

    def surface_static(self, x, y):
        nz = self.nz
        X = np.asarray(x) - self.cx
        Y = np.asarray(y) - self.cy
        dx, dy = nz["dome_center_dxy_m"]
        sx, sy = nz["surface_slope_xy"]
        z = (nz["nominal_surface_z"] + nz["surface_offset_m"]
             - (X - dx) ** 2 / (2 * nz["dome_radius_x_m"])
             - (Y - dy) ** 2 / (2 * nz["dome_radius_y_m"])
             + sx * X + sy * Y)
        for s, h in nz["site_bump_m"].items():
            ox, oy = SITES[s]
            z = z + h * np.exp(-((X - ox) ** 2 + (Y - oy) ** 2) / (2 * BUMP_W ** 2))
        return z

    def site_field(self, x, y, values: dict, width: float, mode: str):
        """mode 'patch': 1 + sum (v_i-1) G_i ; mode 'interp': kernel interpolation."""
        X = np.asarray(x) - self.cx
        Y = np.asarray(y) - self.cy
        num = np.zeros_like(X, dtype=float)
        den = np.zeros_like(X, dtype=float)
        for s, v in values.items():
            ox, oy = SITES[s]
            g = np.exp(-((X - ox) ** 2 + (Y - oy) ** 2) / (2 * width ** 2))
            if mode == "patch":
                num += (v - 1.0) * g
            else:
                num += v * g
                den += g
        if mode == "patch":
            return 1.0 + num
        return num / np.maximum(den, 1e-300)


# ------------------------------------------------------------------- effects

def draw_effects(names, seed: int, S: float):
    """Returns (truth_effects, details, params)."""
    truth, details, P = {}, {}, {}
    for name in names:
        r = rng_for(seed, "effect", name)
        if name == "sensor_bias":
            v = r.uniform(0.5, 2.0) * r.choice([-1.0, 1.0]) * S
            truth[name] = {"fz_n": v}
            P[name] = v
        elif name == "sensor_delay":
            v = r.uniform(0.015, 0.050) * S
            truth[name] = {"delay_s": v}
            P[name] = v
        elif name == "tissue_inertia":
            v = r.uniform(1.5, 3.0) * S
            truth[name] = {"mass_kg": v}
            P[name] = v
        elif name == "nonlinear_stiffness":
            n0 = r.uniform(1.5, 2.2)
            law = "fung" if r.random() < 0.5 else "power"
            n = 1.0 + (n0 - 1.0) * S
            if law == "power" or abs(n - 1.0) < 1e-6:
                g = power_law(n)
                det = {"law": "power", "F": "k*d_ref*(delta/d_ref)^n", "n": n, "d_ref_m": DELTA_REF}
            else:
                lo, hi = math.log(2e-4), math.log(1e3)
                for _ in range(80):
                    mid = 0.5 * (lo + hi)
                    if fit_exponent(fung_law(math.exp(mid))) > n:
                        lo = mid
                    else:
                        hi = mid
                d0 = math.exp(0.5 * (lo + hi))
                g = fung_law(d0)
                det = {"law": "fung", "F": "k*A*delta0*(exp(delta/delta0)-1), A so that F(d_ref)=k*d_ref",
                       "delta0_m": d0, "d_ref_m": DELTA_REF}
            truth[name] = {"exponent": fit_exponent(g)}
            det["exponent_fit"] = "least squares of log F vs log delta, delta uniform on 2..15 mm, elastic part"
            details[name] = det
            P[name] = g
        elif name == "viscoelastic_relaxation":
            t1 = r.uniform(0.3, 0.8)
            t2 = r.uniform(2.0, 8.0)
            ratio = r.uniform(0.4, 1.0) * S
            w1 = r.uniform(0.3, 0.7)
            P[name] = {"ratio": ratio, "w": [w1, 1 - w1], "tau": [t1, t2]}  # stiffness filled later (needs k)
        elif name == "breathing_motion":
            f = r.uniform(0.2, 0.33)
            A = r.uniform(1.5e-3, 3.5e-3) * S
            var = r.uniform(0.05, 0.10)
            duty = r.uniform(0.38, 0.45)
            amp_var = r.uniform(0.03, 0.08)
            drift_amp = r.uniform(0.2e-3, 0.6e-3) * S
            drift_period = r.uniform(60.0, 150.0)
            drift_phase = r.uniform(0, 2 * math.pi)
            flank = {s: (1.0 if s == "center" else r.uniform(0.5, 1.0)) for s in SITES}
            # breath boundaries on the session clock
            T = 1.0 / f
            b = [-r.uniform(0, T)]
            amps = []
            while b[-1] < 4000.0:
                b.append(b[-1] + T * (1 + var * r.uniform(-1, 1)))
                amps.append(A * (1 + amp_var * r.uniform(-1, 1)))
            P[name] = {"A": A, "duty": duty, "b": np.array(b), "amps": np.array(amps),
                       "drift_amp": drift_amp, "drift_period": drift_period, "drift_phase": drift_phase,
                       "flank": flank}
            truth[name] = {"freq_hz": f, "amplitude_m": A}
            details[name] = {"amplitude_definition": "surface moves between about -A and +A (peak-to-peak 2A) at the centre",
                             "inhale_fraction": duty, "breath_period_variability": var,
                             "breath_amplitude_variability": amp_var,
                             "slow_drift_amplitude_m": drift_amp, "slow_drift_period_s": drift_period,
                             "amplitude_scale_by_site": flank}
        elif name == "site_heterogeneity":
            nsites = 1 if r.random() < 0.5 else 2
            chosen = list(r.choice(list(SITES), size=nsites, replace=False))
            scales = {s: 1.0 for s in SITES}
            for s in chosen:
                m = r.uniform(0.25, 0.50)
                # scale acts on log-stiffness so that large --scale never gives k <= 0
                scales[s] = (1.0 + m) ** S if r.random() < 0.5 else (1.0 - m) ** S
            truth[name] = {"stiffness_by_site": scales}
            details[name] = {"spatial_form": "k(x,y)=k*(1+sum_i (s_i-1)*exp(-r_i^2/(2 w^2)))", "w_m": STIFF_W,
                             "applies_to": "elastic and relaxing stiffness"}
            P[name] = scales
        elif name == "sliding_friction":
            mu = r.uniform(0.2, 0.5) * S
            bvis = r.uniform(5.0, 30.0) * S
            truth[name] = {"mu": mu, "viscous_ns_per_m": bvis}
            details[name] = {"v0_m_per_s": FRICTION_V0, "form": "-(mu*Fn*tanh(|v|/v0) + b*|v|) v/|v| while in contact"}
            P[name] = (mu, bvis)
        elif name == "sensor_filter":
            fc = r.uniform(3.0, 10.0) / S if S > 0 else float("inf")
            truth[name] = {"cutoff_hz": fc}
            details[name] = {"form": "first order low-pass on fx,fy,fz, state initialised at the first value"}
            P[name] = fc
        elif name == "bias_drift":
            start = r.uniform(-0.3, 0.3) * S
            total = r.uniform(0.8, 2.5) * r.choice([-1.0, 1.0]) * S
            truth[name] = {"total_n": total, "fz_n": start}
            details[name] = {"form": "fz offset linear in session time from the first to the last sample"}
            P[name] = (start, total)
        elif name == "depth_dependent_damping":
            ratio = r.uniform(2.0, 5.0) * S
            p = r.uniform(1.0, 1.5)
            truth[name] = {"ratio_at_10mm": ratio}
            details[name] = {"form": "c_extra*(delta/10mm)^p*d(delta)/dt, c_extra = ratio*c", "p": p}
            P[name] = (ratio, p)
        else:
            raise SystemExit(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}")
    return truth, details, P


def breath_z(bp, t):
    b, amps = bp["b"], bp["amps"]
    i = np.clip(np.searchsorted(b, t, side="right") - 1, 0, len(amps) - 1)
    s = (t - b[i]) / (b[i + 1] - b[i])
    d = bp["duty"]
    w = np.where(s < d, 0.5 * (1 - np.cos(np.pi * s / d)), 0.5 * (1 + np.cos(np.pi * (s - d) / (1 - d))))
    z = 2 * amps[i] * w - bp["A"]
    z = z + bp["drift_amp"] * np.sin(2 * np.pi * t / bp["drift_period"] + bp["drift_phase"])
    return z


# ----------------------------------------------------------------- sessions

def op_duration(op):
    if op[0] == "hold":
        return op[1]
    if op[0] == "move":
        return abs(op[2]) / op[3] + op[4]
    if op[0] == "chirp":
        return op[4]
    raise ValueError(op)


def build_traj(p0, ops):
    chunks = [np.array(p0, float)[None, :]]
    cur = np.array(p0, float)
    for op in ops:
        if op[0] == "hold":
            n = max(1, int(round(op[1] / DT)))
            P = np.repeat(cur[None], n, 0)
        elif op[0] == "move":
            _, axis, delta, speed, tr = op
            n = max(2, int(round((abs(delta) / speed + tr) / DT)))
            nr = max(1, min(int(round(tr / DT)), n // 2))
            prof = np.ones(n)
            ramp = 0.5 * (1 - np.cos(np.pi * (np.arange(nr) + 0.5) / nr))
            prof[:nr] = ramp
            prof[n - nr:] = ramp[::-1]
            s = np.cumsum(prof)
            s /= s[-1]
            P = np.repeat(cur[None], n, 0)
            P[:, axis] += delta * s
        elif op[0] == "chirp":
            _, A, f0, f1, T, rin, rout = op
            n = int(round(T / DT))
            t = np.arange(1, n + 1) * DT
            K = math.log(f1 / f0)
            phase = 2 * np.pi * f0 * T / K * (np.exp(t / T * K) - 1)
            env = np.ones(n)
            env = np.where(t < rin, 0.5 * (1 - np.cos(np.pi * t / rin)), env)
            env = np.where(t > T - rout, 0.5 * (1 - np.cos(np.pi * (T - t) / rout)), env)
            env[-1] = 0.0
            P = np.repeat(cur[None], n, 0)
            P[:, 2] -= A * env * np.sin(phase)
        else:
            raise ValueError(op)
        chunks.append(P)
        cur = P[-1].copy()
    return np.concatenate(chunks)


def plan_press(r):
    h0 = r.uniform(0.02, 0.03)
    hover = r.uniform(3e-3, 6e-3)
    head = [("hold", r.uniform(0.8, 1.5)), ("move", 2, -(h0 - hover), r.uniform(0.025, 0.035), 0.15),
            ("hold", r.uniform(0.5, 1.0))]
    presses = []
    for _ in range(int(r.choice([2, 2, 3]))):
        d = r.uniform(4e-3, 16e-3)
        travel = hover + d
        v = r.uniform(max(4e-3, travel / 3.0), 20e-3)
        tr = r.uniform(0.08, 0.2)
        presses.append({"depth_m": d, "speed_m_per_s": v,
                        "ops": [("move", 2, -travel, v, tr), ("hold", r.uniform(2.0, 4.0)),
                                ("move", 2, travel, v, tr), ("hold", r.uniform(0.8, 1.5))]})
    tail = [("move", 2, h0 - hover, 0.03, 0.15), ("hold", r.uniform(0.5, 1.0))]

    def total(pr):
        return sum(op_duration(o) for o in head + [o for p in pr for o in p["ops"]] + tail)

    while total(presses) > 29.5 and len(presses) > 2:
        presses.pop()
    while total(presses) > 29.5:  # shorten holds
        for p in presses:
            p["ops"][1] = ("hold", max(2.0, p["ops"][1][1] - 0.25))
            p["ops"][3] = ("hold", max(0.8, p["ops"][3][1] - 0.25))
        if all(p["ops"][1][1] <= 2.0 and p["ops"][3][1] <= 0.8 for p in presses):
            break
    if total(presses) < 10.5:
        tail[-1] = ("hold", tail[-1][1] + 10.5 - total(presses))
    ops = head + [o for p in presses for o in p["ops"]] + tail
    info = {"approach_height_m": h0, "hover_height_m": hover,
            "presses": [{"depth_m": p["depth_m"], "speed_m_per_s": p["speed_m_per_s"]} for p in presses]}
    return h0, ops, info


def plan_chirp(r):
    h0 = r.uniform(0.02, 0.03)
    hover = r.uniform(3e-3, 5e-3)
    d = r.uniform(5e-3, 8e-3)
    A = r.uniform(1.5e-3, 2.5e-3)
    Tc = r.uniform(17.0, 20.0)
    pre = [("hold", r.uniform(0.6, 1.2)), ("move", 2, -(h0 - hover), 0.03, 0.15),
           ("move", 2, -(hover + d), 0.01, 0.15), ("hold", r.uniform(1.0, 1.8))]
    post = [("hold", r.uniform(0.5, 1.0)), ("move", 2, hover + d, 0.012, 0.15),
            ("move", 2, h0 - hover, 0.03, 0.15), ("hold", r.uniform(0.4, 0.8))]
    rest = sum(op_duration(o) for o in pre + post)
    Tc = min(Tc, 29.5 - rest)
    ops = pre + [("chirp", A, 0.3, 5.0, Tc, 1.0, 0.5)] + post
    info = {"approach_height_m": h0, "hold_depth_m": d, "amplitude_m": A, "f0_hz": 0.3, "f1_hz": 5.0,
            "sweep": "exponential", "sweep_s": Tc}
    return h0, ops, info


def plan_slide(r, body, used):
    h0 = r.uniform(0.02, 0.03)
    hover = r.uniform(3e-3, 5e-3)
    d = r.uniform(5e-3, 8e-3)
    v = r.uniform(0.01, 0.02)
    L = 0.03
    cands = []
    for s in SITES:
        x0, y0 = body.site_xy(s)
        z0 = float(body.surface_static(x0, y0))
        for axis in (0, 1):
            off = np.linspace(-L, L, 61)
            xs = x0 + (off if axis == 0 else 0 * off)
            ys = y0 + (off if axis == 1 else 0 * off)
            dz = body.surface_static(xs, ys) - z0
            if d + dz.min() >= 3e-3 - 1e-3 and d + dz.max() <= 12e-3 and (s, axis) not in used:
                cands.append((s, axis))
    if not cands:
        cands = [("center", 0)]
    site, axis = cands[int(r.integers(len(cands)))]
    tr = 0.2
    ops = [("hold", r.uniform(0.6, 1.2)), ("move", 2, -(h0 - hover), 0.03, 0.15),
           ("move", 2, -(hover + d), 0.008, 0.15), ("hold", r.uniform(1.0, 2.0)),
           ("move", axis, L, v, tr), ("hold", 0.5), ("move", axis, -2 * L, v, tr), ("hold", 0.5),
           ("move", axis, L, v, tr), ("hold", r.uniform(0.5, 1.0)),
           ("move", 2, hover + d, 0.01, 0.15), ("move", 2, h0 - hover, 0.03, 0.15), ("hold", r.uniform(0.4, 0.8))]
    info = {"approach_height_m": h0, "depth_m": d, "axis": "xy"[axis], "half_length_m": L, "speed_m_per_s": v,
            "path": "0 -> +L -> -L -> 0"}
    return site, axis, h0, ops, info


def plan_session(seed: int, body: Body, write_session_time: bool):
    r = rng_for(seed, "session")
    items = [("press", s) for s in r.permutation(list(SITES))]
    chirp_sites = list(r.choice(list(SITES), size=2, replace=False))
    items += [("chirp", s) for s in chirp_sites]
    items += [("slide", None), ("slide", None)]
    items += [("press", str(r.choice(list(SITES))))]
    n_extra = int(r.choice([0, 0, 0, 1, 2]))
    for _ in range(n_extra):
        items.append((str(r.choice(["press", "chirp"])), str(r.choice(list(SITES)))))
    first = items[0]
    rest = [items[i] for i in r.permutation(np.arange(1, len(items)))]
    items = [first] + rest
    recs = []
    used_slides = set()
    t_sess = 0.0
    include_vel = seed % 2 == 1
    for i, (proto, site) in enumerate(items):
        if proto == "press":
            h0, ops, info = plan_press(r)
            axis = None
        elif proto == "chirp":
            h0, ops, info = plan_chirp(r)
        else:
            site, axis, h0, ops, info = plan_slide(r, body, used_slides)
            used_slides.add((site, axis))
        sx, sy = body.site_xy(site)
        ex, ey = r.normal(0, body.nz["placement_error_sigma_m"], 2)
        x0, y0 = sx + ex, sy + ey
        plan_err = r.uniform(-1, 1) * body.nz["planning_surface_error_max_m"]
        z_plan = float(body.surface_static(x0, y0)) + plan_err
        P = build_traj((x0, y0, z_plan + h0), ops)
        rate = int(r.choice(RATES))
        jitter = bool(r.random() < 0.5)
        pause = float(r.uniform(5.0, 30.0))
        dur = (len(P) - 1) * DT
        rec = {"file": f"{i:02d}_{site}_{proto}.csv", "site": site, "protocol": proto,
               "rate_hz": rate, "timestamp_jitter": jitter, "duration_s": dur,
               "start_xy": [x0, y0], "planned_surface_error_m": plan_err,
               "true_site_surface_z_m": float(body.surface_static(sx, sy)), "plan": info, "P": P}
        recs.append(rec)
        rec["session_time_s"] = t_sess
        t_sess += dur + (pause if write_session_time else 0.0)
    return recs, include_vel


# ---------------------------------------------------------------- simulation

def body_force(body: Body, P: np.ndarray, t_sess0: float, eff: dict) -> np.ndarray:
    nz = body.nz
    N = len(P)
    tf = np.arange(N) * DT
    x, y, z = P[:, 0], P[:, 1], P[:, 2]
    zs = body.surface_static(x, y)
    if "breathing_motion" in eff:
        bp = eff["breathing_motion"]
        zs = zs + breath_z(bp, t_sess0 + tf) * body.site_field(x, y, bp["flank"], BREATH_W, "interp")
    delta = zs - z
    ddelta = np.gradient(delta, DT)
    contact = delta > 0
    u = np.maximum(delta, 0.0)
    k = nz["k_n_per_m"]
    c = nz["c_ns_per_m"]
    sk = body.site_field(x, y, eff["site_heterogeneity"], STIFF_W, "patch") if "site_heterogeneity" in eff else 1.0
    g = eff.get("nonlinear_stiffness")
    F = k * sk * (g(u) if g is not None else u)
    cd = c * (-np.expm1(-u / DAMP_SMOOTH))
    if "depth_dependent_damping" in eff:
        ratio, p = eff["depth_dependent_damping"]
        cd = cd + ratio * c * (u / 0.01) ** p
    F = F + cd * ddelta
    if "viscoelastic_relaxation" in eff:
        vp = eff["viscoelastic_relaxation"]
        du = np.diff(u, prepend=u[0]) * sk
        for ki, tau in zip(vp["k"], vp["tau"]):
            F = F + expfilt(ki * du, math.exp(-DT / tau), 1.0)
    if "tissue_inertia" in eff:
        az = np.gradient(np.gradient(z, DT), DT)
        F = F - eff["tissue_inertia"] * az
    Fn = np.where(contact, np.maximum(F, 0.0), 0.0)
    f = Fn[:, None] * body.nhat[None, :]
    if "sliding_friction" in eff:
        mu, b = eff["sliding_friction"]
        v = np.gradient(P[:, :2], DT, axis=0)
        sp = np.hypot(v[:, 0], v[:, 1])
        mag = mu * Fn * np.tanh(sp / FRICTION_V0) + b * sp * (Fn > 0)
        f[:, :2] -= (mag / np.maximum(sp, 1e-12))[:, None] * v
    return f


def sample_times(r, dur, rate, jitter):
    n = int(math.floor(dur * rate + 1e-9)) + 1
    t = np.arange(n) / rate
    if jitter:
        t[1:] += r.uniform(-0.02, 0.02, n - 1) / rate
        t = t[t <= dur]
    return t


def generate(effects, seed: int, out: str, scale: float = 1.0, quiet=False):
    effects = [e for e in effects if e and e != "none"]
    for e in effects:
        if e not in EFFECTS:
            raise SystemExit(f"unknown effect {e!r}; known: {', '.join(EFFECTS)}")
    nz = draw_nuisances(seed)
    body = Body(nz)
    truth_eff, details, eff = draw_effects(effects, seed, scale)
    if "viscoelastic_relaxation" in eff:
        vp = eff["viscoelastic_relaxation"]
        vp["k"] = [vp["ratio"] * w * nz["k_n_per_m"] for w in vp["w"]]
        tot = sum(vp["k"])
        truth_eff["viscoelastic_relaxation"] = {
            "branches": [{"tau_s": t, "stiffness_n_per_m": kk} for t, kk in zip(vp["tau"], vp["k"])],
            "tau_s": (sum(t * kk for t, kk in zip(vp["tau"], vp["k"])) / tot) if tot > 0 else 0.0,
            "ratio": vp["ratio"],
        }
        details["viscoelastic_relaxation"] = {"form": "two Maxwell branches driven by indentation max(delta,0)"}
    write_st = "bias_drift" in effects or seed % 3 != 0
    recs, include_vel = plan_session(seed, body, write_st)

    ds_dir = os.path.join(out, "dataset")
    os.makedirs(ds_dir, exist_ok=True)
    # session clock bounds (first and last sample)
    rec_times = []
    for i, rec in enumerate(recs):
        rn = rng_for(seed, "timestamps", i)
        rec_times.append(sample_times(rn, rec["duration_s"], rec["rate_hz"], rec["timestamp_jitter"]))
    T_first = recs[0]["session_time_s"] + rec_times[0][0]
    T_last = recs[-1]["session_time_s"] + rec_times[-1][-1]

    listing = []
    for i, rec in enumerate(recs):
        P = rec["P"]
        N = len(P)
        tf = np.arange(N) * DT
        f = body_force(body, P, rec["session_time_s"], eff)
        # sensor chain: delay -> low-pass -> sample -> bias/drift -> noise
        if "sensor_delay" in eff and eff["sensor_delay"] > 0:
            f = np.stack([np.interp(tf - eff["sensor_delay"], tf, f[:, j]) for j in range(3)], 1)
        if "sensor_filter" in eff and math.isfinite(eff["sensor_filter"]):
            a = math.exp(-2 * math.pi * eff["sensor_filter"] * DT)
            f = np.stack([expfilt(f[:, j], a, 1 - a, f[0, j]) for j in range(3)], 1)
        t = rec_times[i]
        fs = np.stack([np.interp(t, tf, f[:, j]) for j in range(3)], 1)
        ps = np.stack([np.interp(t, tf, P[:, j]) for j in range(3)], 1)
        if "sensor_bias" in eff:
            fs[:, 2] += eff["sensor_bias"]
        if "bias_drift" in eff:
            b0, tot = eff["bias_drift"]
            fs[:, 2] += b0 + tot * (rec["session_time_s"] + t - T_first) / (T_last - T_first)
        rn = rng_for(seed, "noise", i)
        a = math.exp(-2 * math.pi * nz["force_noise_cutoff_hz"] * DT)
        col = np.stack([expfilt(rn.standard_normal(N), a, 1 - a) for _ in range(3)], 1)
        col *= nz["force_noise_sigma_n"] / math.sqrt((1 - a) / (1 + a))
        col[:, :2] *= nz["tangential_noise_factor"]
        noise = np.stack([np.interp(t, tf, col[:, j]) for j in range(3)], 1)
        noise += rn.normal(0, nz["force_white_sigma_n"], (len(t), 3))
        fs += noise
        pm = ps + rn.normal(0, nz["encoder_sigma_m"], ps.shape)
        cols = [t[:, None], pm, fs]
        header = "t,px,py,pz,fx,fy,fz"
        fmt = ["%.9g"] + ["%.8g"] * 3 + ["%.6g"] * 3
        if include_vel:
            V = np.gradient(P, DT, axis=0)
            vs = np.stack([np.interp(t, tf, V[:, j]) for j in range(3)], 1)
            vs += rn.normal(0, nz["velocity_noise_sigma_m_per_s"], vs.shape)
            cols.append(vs)
            header += ",vx,vy,vz"
            fmt += ["%.6g"] * 3
        data = np.hstack(cols)
        np.savetxt(os.path.join(ds_dir, rec["file"]), data, fmt=fmt, delimiter=",", header=header, comments="")
        entry = {"file": rec["file"], "site": rec["site"], "protocol": rec["protocol"]}
        if write_st:
            entry["session_time_s"] = round(rec["session_time_s"], 6)
        listing.append(entry)
        rec["n_samples"] = int(len(t))

    dataset = {
        "format": FORMAT,
        "description": "Bench recordings of an ultrasound probe pressing a soft torso phantom "
                       "(independent test bench).",
        "nominal_surface_z": nz["nominal_surface_z"],
        "torso_center_xy": nz["torso_center_xy"],
        "recordings": listing,
        "notes": "Probe tip position from joint encoders (commanded trajectory); force from a wrist F/T "
                 "sensor expressed in the world frame, force of the body on the probe." +
                 (" session_time_s is seconds since the first recording started." if write_st else
                  " Recordings were taken back to back."),
        "rig": {"name": "indep-bench", "operator": "synthetic"},
    }
    with open(os.path.join(ds_dir, "dataset.json"), "w") as fh:
        json.dump(dataset, fh, indent=2)

    nuis = dict(nz)
    nuis["site_surface_z_m"] = {s: float(body.surface_static(*body.site_xy(s))) for s in SITES}
    nuis["session_time_written"] = write_st
    nuis["velocity_columns"] = include_vel
    nuis["recordings"] = [{k: v for k, v in rec.items() if k != "P"} for rec in recs]
    truth = {"effects": truth_eff, "effect_details": details, "nuisances": nuis,
             "generator": "independent_data/generate.py", "seed": seed, "scale": scale}
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2, default=float)
    if not quiet:
        tot = sum(r["duration_s"] for r in recs)
        print(f"wrote {out}: {len(recs)} recordings, {tot:.0f} s, effects={effects or ['none']}")
    return truth


def case_list():
    cases = [["none"]] + [[e] for e in EFFECTS] + [list(p) for p in PAIRS]
    return cases


# -------------------------------------------------------------------- check

HEADERS = ("t,px,py,pz,fx,fy,fz", "t,px,py,pz,fx,fy,fz,vx,vy,vz")


def load_dataset(ds_dir):
    problems = []
    with open(os.path.join(ds_dir, "dataset.json")) as fh:
        meta = json.load(fh)
    if meta.get("format") != FORMAT:
        problems.append("bad format tag")
    for key in ("nominal_surface_z", "torso_center_xy", "recordings"):
        if key not in meta:
            problems.append(f"missing {key}")
    recs = []
    prev_st = -1.0
    for rec in meta["recordings"]:
        path = os.path.join(ds_dir, rec["file"])
        with open(path) as fh:
            head = fh.readline().strip()
        if head not in HEADERS:
            problems.append(f"{rec['file']}: header {head!r}")
        d = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        t = d[:, 0]
        if not np.all(np.isfinite(d)):
            problems.append(f"{rec['file']}: non-finite values")
        if t[0] != 0.0:
            problems.append(f"{rec['file']}: t starts at {t[0]}")
        dt = np.diff(t)
        if not np.all(dt > 0):
            problems.append(f"{rec['file']}: t not increasing")
        rate = 1.0 / np.median(dt)
        if not (100 * 0.99 <= rate <= 2000 * 1.01):
            problems.append(f"{rec['file']}: rate {rate:.1f}")
        if dt.max() * rate > 1.05 or dt.min() * rate < 0.95:
            problems.append(f"{rec['file']}: jitter beyond 5%")
        if not (10 <= t[-1] <= 30.01):
            problems.append(f"{rec['file']}: duration {t[-1]:.2f}")
        if rec["site"] not in SITES or rec["protocol"] not in ("press", "chirp", "slide"):
            problems.append(f"{rec['file']}: bad site/protocol")
        if "session_time_s" in rec:
            if rec["session_time_s"] < prev_st:
                problems.append(f"{rec['file']}: session_time_s decreasing")
            prev_st = rec["session_time_s"] + t[-1]
        recs.append((rec, d, rate, bool(np.ptp(dt) * rate > 1e-3)))
    return meta, recs, problems


def check(root):
    names = sorted(n for n in os.listdir(root) if os.path.isfile(os.path.join(root, n, "truth.json")))
    base = {}
    summary = []
    n_bad = 0
    for name in sorted(names, key=lambda n: (not n.startswith("none-"), n)):
        truth = json.load(open(os.path.join(root, name, "truth.json")))
        meta, recs, problems = load_dataset(os.path.join(root, name, "dataset"))
        seed = truth["seed"]
        nz = truth["nuisances"]
        sig = math.hypot(nz["force_noise_sigma_n"], nz["force_white_sigma_n"])
        if not truth["effects"]:
            base[seed] = recs
        effs = "; ".join(f"{e}({', '.join(f'{k}={v:.4g}' for k, v in p.items() if isinstance(v, (int, float)))})"
                         for e, p in truth["effects"].items()) or "none"
        tot = sum(d[-1, 0] for _, d, _, _ in recs)
        print(f"== {name}  {len(recs)} recs {tot:.0f} s  noise sigma {sig:.3f} N  effects: {effs}")
        for p in problems:
            print(f"   PROBLEM: {p}")
        n_bad += len(problems)
        ratios = []
        sq, cnt = 0.0, 0
        for j, (rec, d, rate, jit) in enumerate(recs):
            line = (f"   {rec['file']:<26} {rate:6.0f} Hz{'~' if jit else ' '} {d[-1, 0]:5.1f} s"
                    f"  max fz {d[:, 6].max():7.2f} N  min fz {d[:, 6].min():6.2f}")
            if truth["effects"] and seed in base:
                b = base[seed][j][1]
                if b.shape != d.shape or not np.allclose(b[:, :4], d[:, :4]):
                    line += "  (time base/positions differ from none!)"
                    n_bad += 1
                else:
                    diff = d[:, 4:7] - b[:, 4:7]
                    rms = float(np.sqrt(np.mean(np.sum(diff ** 2, 1))))
                    sq += float(np.sum(diff ** 2))
                    cnt += len(diff)
                    ratios.append(rms / sig)
                    line += f"  d_rms {rms:6.3f} N ({rms / sig:5.1f}x sigma)"
            print(line)
        if ratios:
            summary.append((name, math.sqrt(sq / cnt) / sig, max(ratios), min(ratios)))
    if summary:
        print("\n== effect visibility vs the no-effect case of the same seed (RMS |df| / noise sigma)")
        print(f"   {'case':<52} {'overall':>8} {'max rec':>8} {'min rec':>8}")
        for name, o, mx, mn in summary:
            print(f"   {name:<52} {o:8.1f} {mx:8.1f} {mn:8.1f}")
    print(f"\n{len(names)} datasets checked, {n_bad} problems")
    return n_bad


# --------------------------------------------------------------------- main

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--effects", help="comma separated effect names, or 'none'")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seeds", default="1,2,3", help="seeds for --matrix")
    ap.add_argument("--out")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--matrix", action="store_true")
    ap.add_argument("--check", metavar="DIR", help="validate a --matrix output folder")
    a = ap.parse_args(argv)
    if a.check:
        return 1 if check(a.check) else 0
    if not a.out:
        ap.error("--out is required")
    if a.matrix:
        t0 = time.time()
        for seed in [int(s) for s in a.seeds.split(",") if s.strip()]:
            for case in case_list():
                name = "+".join(case)
                generate(case, seed, os.path.join(a.out, f"{name}-s{seed}"), a.scale)
        print(f"matrix done in {time.time() - t0:.0f} s")
        return 0
    if a.effects is None:
        ap.error("--effects is required (or --matrix / --check)")
    generate([e.strip() for e in a.effects.split(",")], a.seed, a.out, a.scale)
    return 0


if __name__ == "__main__":
    sys.exit(main())
