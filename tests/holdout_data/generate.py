#!/usr/bin/env python3
"""Blind hold-out datasets for `echogym calibrate` (generator "holdout-3").

Written from the `echogym-recordings/1` format and the effect catalogue's names, physics
and keys only: its body, protocol, sensor and effect models are its own (README.md beside
this file documents every one). Python 3 + numpy.

  generate.py --effects sensor_bias,breathing_motion --seed 3 --out DIR   # DIR/dataset, DIR/truth.json
  generate.py --effects none --seed 3 --out DIR
  generate.py --matrix --seeds 11,12 --out DIR       # DIR/<case>-s<seed>/{dataset/,truth.json}
  generate.py --check DIR                            # effect size vs none, format validation
"""
import argparse
import json
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np

GENERATOR = "holdout-3"
FORMAT = "echogym-recordings/1"
EFFECTS = ["sensor_bias", "sensor_delay", "tissue_inertia", "nonlinear_stiffness",
           "viscoelastic_relaxation", "breathing_motion", "site_heterogeneity",
           "sliding_friction", "sensor_filter", "bias_drift", "depth_dependent_damping"]
CONTACT_EFFECTS = ["tissue_inertia", "nonlinear_stiffness", "viscoelastic_relaxation",
                   "site_heterogeneity", "sliding_friction", "depth_dependent_damping"]
SENSOR_EFFECTS = ["sensor_bias", "sensor_delay", "sensor_filter", "bias_drift"]
# Site offsets from the torso centre [m] (the five named in docs/data.md).
SITES = {"center": (0.0, 0.0), "upper_left": (-0.06, 0.08), "upper_right": (0.06, 0.08),
         "lower_left": (-0.06, -0.08), "lower_right": (0.06, -0.08)}
RATES = [50, 100, 125, 200, 500, 1000, 2000]
DT = 0.25e-3          # body integration grid [s]
MM = 1e-3
VISIBLE = 3.5         # target RMS |dF| in noise sigmas (the check asks >= 3)


# ----------------------------------------------------------------------------- numerics
def ar1(u, d, y0=0.0):
    """y[k] = exp(-d[k]) * y[k-1] + u[k] with y[-1] = y0, vectorised in blocks."""
    u = np.asarray(u, float)
    n = u.size
    if n == 0:
        return u.copy()
    d = np.minimum(np.broadcast_to(np.asarray(d, float), (n,)), 25.0)
    big = np.cumsum(d)
    y = np.empty(n)
    prev, start = float(y0), 0
    while start < n:
        base = big[start - 1] if start else 0.0
        end = max(int(np.searchsorted(big, base + 25.0, side="right")), start + 1)
        e = np.exp(big[start:end] - base)
        y[start:end] = (prev + np.cumsum(u[start:end] * e)) / e
        prev, start = y[end - 1], end
    return y


def lowpass1(x, dt, tau, y0=None):
    """Exact first-order low-pass (time constant tau) of x sampled every dt."""
    a = math.exp(-dt / tau)
    return ar1((1.0 - a) * np.asarray(x, float), dt / tau, x[0] if y0 is None else y0)


def ou(rng, t, sigma, tau):
    """Ornstein-Uhlenbeck noise (stationary std sigma, time constant tau) at instants t."""
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]) if t.size > 1 else 0.0)
    d = dt / tau
    u = sigma * np.sqrt(-np.expm1(-2.0 * np.minimum(d, 25.0))) * rng.standard_normal(t.size)
    u[0] = sigma * rng.standard_normal()
    return ar1(u, d, 0.0)


def minjerk(tk, vk, t):
    """Minimum-jerk (quintic) blend through knots (tk, vk); vk shape (m,) or (m, dims)."""
    tk = np.asarray(tk, float)
    vk = np.asarray(vk, float)
    i = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, len(tk) - 2)
    tau = np.clip((t - tk[i]) / (tk[i + 1] - tk[i]), 0.0, 1.0)
    s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
    if vk.ndim == 1:
        return vk[i] + s * (vk[i + 1] - vk[i])
    return vk[i] + s[:, None] * (vk[i + 1] - vk[i])


def loglog_slope(fn, lo, hi):
    d = np.geomspace(lo, hi, 60)
    return float(np.polyfit(np.log(d), np.log(fn(d)), 1)[0])


def bisect(f, lo, hi, target, increasing, iters=60, geometric=True):
    for _ in range(iters):
        mid = math.sqrt(lo * hi) if geometric else 0.5 * (lo + hi)
        if (f(mid) < target) == increasing:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi) if geometric else 0.5 * (lo + hi)


# ----------------------------------------------------------------------------- geometry
def surface(geo, x, y):
    """Static skin height [m] at world (x, y): a dome with a tilt and local bumps."""
    cx, cy = geo["center_xy"]
    dx, dy = x - cx, y - cy
    z = (geo["z_center"] - dx * dx / (2 * geo["radius_x_m"]) - dy * dy / (2 * geo["radius_y_m"])
         + geo["slope_x"] * dx + geo["slope_y"] * dy)
    for b in geo["bumps"]:
        z = z + b["height_m"] * np.exp(-((dx - b["dx_m"]) ** 2 + (dy - b["dy_m"]) ** 2)
                                       / (2 * b["width_m"] ** 2))
    return z


def breath_profile(geo, x, y):
    cx, cy = geo["center_xy"]
    e = geo["breath_edge_drop"]
    return np.clip(1.0 - e * (((x - cx) / 0.10) ** 2 + ((y - cy) / 0.12) ** 2), 0.2, 1.0)


# ----------------------------------------------------------------------------- protocol
def press_knots(rng, dur, air):
    """Depth knots (time, depth; negative = above the skin) of a press recording."""
    tk, vk = [0.0], [-air]
    go = lambda v, d: (tk.append(tk[-1] + max(d, 0.05)), vk.append(v))

    v_air = rng.uniform(12, 25) * MM
    go(-air, rng.uniform(1.0, 3.0))
    stair = rng.random() < 0.3
    first, partial = True, 0
    while True:
        vp = rng.uniform(3, 20) * MM
        if stair:
            steps = np.minimum(np.cumsum(rng.uniform(2.0, 4.5, 3)) * MM, 15 * MM)
            holds = rng.uniform(2.0, 4.0, 3)
        else:
            steps = [rng.uniform(4.0, 15.0) * MM]
            holds = [rng.uniform(2.0, 5.0)]
        to_air = rng.random() < 0.6 or partial >= 2     # <= 2 partial releases in a row
        partial = 0 if to_air else partial + 1
        rel_depth = rng.uniform(1.0, 2.0) * MM
        dwell = rng.uniform(1.0, 2.0) if to_air else rng.uniform(0.5, 1.5)
        seq, cur = [], vk[-1]
        if cur < 0:
            seq.append((-1 * MM, (abs(cur) - 1 * MM) / v_air))
            cur = -1 * MM
        for d, h in zip(steps, holds):
            seq += [(d, abs(d - cur) / vp), (d, h)]
            cur = d
        rel = -air if to_air else rel_depth
        seq += [(rel, abs(cur - rel) / (v_air if to_air else vp)), (rel, dwell)]
        need = sum(s[1] for s in seq) + (rel + air) / v_air + 1.0
        if not first and tk[-1] + need > dur:
            break
        for v, d in seq:
            go(v, d)
        first = False
    if vk[-1] > -air:
        go(-air, (vk[-1] + air) / v_air)
    return finish_knots(tk, vk, dur)


def finish_knots(tk, vk, dur):
    tk = np.array(tk)
    if tk[-1] > dur - 1.0:                       # compress to leave >= 1 s of free air
        tk = tk * (dur - 1.0) / tk[-1]
    return np.append(tk, dur + 0.01), np.append(np.array(vk), [vk[-1]], axis=0)


def osc_signal(rng, dur, t_on, t_off):
    """Irregular depth oscillation (zero mean, unit-free) for the chirp-like recordings."""
    kind = "sines" if rng.random() < 0.5 else "band_noise"
    if kind == "sines":
        k = int(rng.integers(3, 7))
        f = np.exp(np.linspace(math.log(0.3), math.log(8.0), k + 1)[:-1] + rng.uniform(0, math.log(8 / 0.3) / k, k))
        a = f ** -0.3 * rng.uniform(0.5, 1.5, k)
        ph = rng.uniform(0, 2 * math.pi, k)
        fam, pam = rng.uniform(0.05, 0.2, k), rng.uniform(0, 2 * math.pi, k)
        comp = dict(kind=kind, freqs_hz=f, amps=a, phases=ph, am_hz=fam, am_phase=pam)
    else:
        k, fmax = 40, rng.uniform(4.0, 8.0)
        f = rng.uniform(0.15, fmax, k)
        a = rng.rayleigh(1.0, k) / (1.0 + f / 3.0)
        ph = rng.uniform(0, 2 * math.pi, k)
        comp = dict(kind=kind, freqs_hz=f, amps=a, phases=ph, am_hz=np.zeros(k),
                    am_phase=np.zeros(k), fmax_hz=fmax)
    comp.update(t_on=t_on, t_off=t_off, target_rms_m=rng.uniform(0.9, 2.0) * MM)
    return comp


def eval_osc(c, t):
    o = np.zeros_like(t)
    for f, a, p, fa, pa in zip(c["freqs_hz"], c["amps"], c["phases"], c["am_hz"], c["am_phase"]):
        am = 1.0 + (0.3 * np.sin(2 * math.pi * fa * t + pa) if fa > 0 else 0.0)
        o += a * am * np.sin(2 * math.pi * f * t + p)
    ramp = 1.0
    env = np.clip(np.minimum((t - c["t_on"]) / ramp, (c["t_off"] - t) / ramp), 0.0, 1.0)
    return o * (0.5 - 0.5 * np.cos(math.pi * env))


def make_base(seed):
    """Everything the seed fixes: torso, session, protocol, timing and noise."""
    rng = np.random.default_rng([seed, 7001])
    geo = dict(center_xy=[float(rng.uniform(0.38, 0.52)), float(rng.uniform(-0.06, 0.06))],
               z_center=float(rng.uniform(0.09, 0.16)),
               radius_x_m=float(rng.uniform(0.7, 2.0)), radius_y_m=float(rng.uniform(0.7, 2.0)),
               slope_x=float(rng.uniform(-0.03, 0.03)), slope_y=float(rng.uniform(-0.03, 0.03)),
               breath_edge_drop=float(rng.choice([0.0, rng.uniform(0.2, 0.6)])))
    geo["bumps"] = [dict(dx_m=float(rng.uniform(-0.1, 0.1)), dy_m=float(rng.uniform(-0.12, 0.12)),
                         height_m=float(rng.choice([-1, 1]) * rng.uniform(0.5, 2.5) * MM),
                         width_m=float(rng.uniform(0.015, 0.04)))
                    for _ in range(int(rng.integers(2, 5)))]
    nominal_z = geo["z_center"] + rng.uniform(-3, 3) * MM
    body = dict(stiffness_n_per_m=float(math.exp(rng.uniform(math.log(600), math.log(3000)))),
                damping_ns_per_m=float(rng.uniform(15, 80)),
                onset_m=float(rng.uniform(0.1, 0.4) * MM),
                force_dir_face_weight=0.7)
    tilt = dict(tilt_deg=float(rng.uniform(0, 3)), azimuth_deg=float(rng.uniform(0, 360)),
                per_recording_jitter_deg=0.3, sensor_to_tip_m=float(rng.uniform(0.12, 0.2)))
    sig = float(math.exp(rng.uniform(math.log(0.02), math.log(0.2))))
    share = rng.dirichlet([3, 2, 0.7])
    noise = dict(fz_sigma_n=sig, white_share=float(share[0]), fast_share=float(share[1]),
                 slow_share=float(share[2]), fast_tau_s=float(rng.uniform(0.03, 0.4)),
                 slow_tau_s=float(rng.uniform(3, 20)), fxy_scale=float(rng.uniform(0.5, 1.0)),
                 torque_sigma_nm=float(rng.uniform(0.002, 0.01)),
                 encoder_sigma_m=float(rng.uniform(10, 60) * 1e-6),
                 encoder_white_share=float(rng.uniform(0.3, 0.7)), encoder_tau_s=0.5,
                 velocity_sigma_m_per_s=float(rng.uniform(0.5, 2.0) * MM))
    cols = dict(torque=bool(rng.random() < 0.5), velocity=bool(rng.random() < 0.3))
    tcp_err = [float(rng.normal(0, 0.7 * MM)), float(rng.normal(0, 0.7 * MM)),
               float(rng.normal(0, 0.4 * MM))]
    place_sigma = float(rng.uniform(2, 5) * MM)
    clock = bool(rng.random() < 0.7)
    while True:
        n = int(rng.integers(8, 15))
        durs = rng.uniform(15, 35, n)
        if 180 <= durs.sum() <= 300:
            break
    n_osc, n_slide = int(rng.integers(2, 4)), int(rng.integers(2, 4))
    while n - n_osc - n_slide < 3:
        n_osc, n_slide = max(2, n_osc - 1), max(2, n_slide - 1)
    kinds = ["press"] * (n - n_osc - n_slide) + ["chirp"] * n_osc + ["slide"] * n_slide
    kinds = list(rng.permutation(kinds))
    kinds.insert(0, kinds.pop(kinds.index("press")))
    others = [s for s in SITES if s != "center"]
    chosen = ["center"] + [str(v) for v in rng.choice(others, int(rng.integers(3, 5)), replace=False)]
    order = list(rng.permutation(chosen))
    recs, s_now, pi = [], float(rng.uniform(0, 60)) if clock else 0.0, 0
    for i, (kind, dur) in enumerate(zip(kinds, durs)):
        dur = float(dur)
        if kind == "press":
            site = order[pi % len(order)]
            pi += 1
        else:
            site = str(rng.choice(chosen))
        sx = geo["center_xy"][0] + SITES[site][0] + rng.normal(0, place_sigma)
        sy = geo["center_xy"][1] + SITES[site][1] + rng.normal(0, place_sigma)
        air = float(rng.uniform(10, 20) * MM)
        rate = int(rng.choice(RATES))
        jitter = float(rng.uniform(0.03, 0.2)) if rng.random() < 0.5 else 0.0
        gap = None
        if rng.random() < 1 / 3:
            gap = [float(rng.uniform(0.25, 0.75) * dur), float(rng.uniform(0.25, 1.5))]
        th = math.radians(tilt["tilt_deg"] + rng.normal(0, 0.3))
        az = math.radians(tilt["azimuth_deg"] + rng.normal(0, 5))
        a_up = np.array([math.sin(th) * math.cos(az), math.sin(th) * math.sin(az), math.cos(th)])
        rec = dict(index=i, kind=kind, site=site, dur=dur, rate=rate, jitter=jitter, gap=gap,
                   S=s_now, xy=[float(sx), float(sy)], air=air, a_up=a_up)
        tf = np.arange(0.0, dur + 0.5 * DT, DT)
        if kind == "press":
            tk, vk = press_knots(rng, dur, air)
            depth = minjerk(tk, vk, tf)
            x, y = np.full_like(tf, sx), np.full_like(tf, sy)
            rec["motion"] = dict(kind="press_hold", knots_s=tk, depth_knots_m=vk)
        elif kind == "chirp":
            dm = rng.uniform(5, 9) * MM
            v_air = rng.uniform(12, 25) * MM
            t1 = rng.uniform(1, 2)
            t2 = t1 + (air + dm) / v_air
            t_on, t_off = t2 + 1.0, dur - rng.uniform(1, 2) - (air + dm) / v_air - 0.5
            comp = osc_signal(rng, dur, t_on, t_off)
            o = eval_osc(comp, tf)
            scale = min(comp["target_rms_m"] / max(np.sqrt(np.mean(o[(tf > t_on) & (tf < t_off)] ** 2)), 1e-12),
                        (dm - 1 * MM) / np.max(np.abs(o)), (15 * MM - dm) / np.max(np.abs(o)))
            tk, vk = np.array([0, t1, t2, t_off + 0.5, t_off + 0.5 + (air + dm) / v_air, dur + 0.01]), \
                np.array([-air, -air, dm, dm, -air, -air])
            depth = minjerk(tk, vk, tf) + scale * o
            x, y = np.full_like(tf, sx), np.full_like(tf, sy)
            rec["motion"] = dict(kind="irregular_depth_oscillation", mean_depth_m=dm, knots_s=tk,
                                 depth_knots_m=vk, oscillation={k: (v.tolist() if isinstance(v, np.ndarray) else v)
                                                                for k, v in comp.items()},
                                 scale_m=float(scale))
        if kind in ("press", "chirp"):
            z = float(surface(geo, sx, sy)) - depth
        else:
            ang = rng.uniform(0, 2 * math.pi)
            u = np.array([math.cos(ang), math.sin(ang)])
            length = rng.uniform(0.03, 0.06)
            p0 = np.array([sx, sy]) - 0.5 * length * u
            d0, mod = rng.uniform(3, 8) * MM, rng.choice([-1, 1]) * rng.uniform(0.8, 2.5) * MM
            h0, h1 = float(surface(geo, *p0)), float(surface(geo, *(p0 + length * u)))
            sg = np.linspace(0, length, 300)
            zp = h0 + (h1 - h0) * sg / length - d0 - mod * np.sin(math.pi * sg / length)
            dep = surface(geo, p0[0] + sg * u[0], p0[1] + sg * u[1]) - zp
            zp = zp - max(0.0, 1.5 * MM - dep.min())
            v, v_air = rng.uniform(8, 30) * MM, rng.uniform(12, 25) * MM
            lift0 = air + (surface(geo, *p0) - zp[0])
            tk = [0.0, rng.uniform(1, 2)]
            tk += [tk[-1] + lift0 / v_air, tk[-1] + lift0 / v_air + rng.uniform(0.5, 1.0)]
            vk = [[0.0, lift0], [0.0, lift0], [0.0, 0.0], [0.0, 0.0]]
            end, first = 0.0, True
            while True:
                hold = rng.uniform(0.3, 1.5)
                if not first and tk[-1] + length / v * 1.2 + hold + lift0 / v_air + 1.0 > dur:
                    break
                end = length - end
                tk += [tk[-1] + length / v * 1.2, tk[-1] + length / v * 1.2 + hold]
                vk += [[end, 0.0], [end, 0.0]]
                first = False
            tk.append(tk[-1] + lift0 / v_air)
            vk.append([end, lift0])
            tk, vk = finish_knots(tk, vk, dur)
            sl = minjerk(tk, vk, tf)
            x, y = p0[0] + sl[:, 0] * u[0], p0[1] + sl[:, 0] * u[1]
            z = np.interp(sl[:, 0], sg, zp) + sl[:, 1]
            rec["motion"] = dict(kind="palpation_sweep", start_xy=p0.tolist(), direction=u.tolist(),
                                 length_m=length, planned_depth_m=d0, depth_modulation_m=mod,
                                 mean_speed_m_per_s=v, knots_s=np.asarray(tk), knots_s_lift=np.asarray(vk))
        # per-recording fine-grid kinematics
        hs = surface(geo, x, y)
        eps = 1e-4
        hx = (surface(geo, x + eps, y) - surface(geo, x - eps, y)) / (2 * eps)
        hy = (surface(geo, x, y + eps) - surface(geo, x, y - eps)) / (2 * eps)
        ns = np.stack([-hx, -hy, np.ones_like(hx)])
        ns /= np.linalg.norm(ns, axis=0)
        w = body["force_dir_face_weight"]
        nd = w * a_up[:, None] + (1 - w) * ns
        nd /= np.linalg.norm(nd, axis=0)
        vx, vy, vz = (np.gradient(q, DT) for q in (x, y, z))
        rec.update(tf=tf, x=x, y=y, z=z, vx=vx, vy=vy, vz=vz, az=np.gradient(vz, DT), hs=hs, nd=nd,
                   prof=breath_profile(geo, x, y), dstat=hs - z)
        # sample instants (jitter: stamp noise around the nominal grid; rare drops; one gap)
        dt = 1.0 / rate
        k = np.arange(int(dur * rate))
        ts = k * dt
        if jitter:
            ts = ts + dt * jitter * np.clip(rng.standard_normal(k.size), -2, 2)
            keep = rng.random(k.size) > 0.003
            keep[0] = True
            ts = ts[keep]
        ts = np.round(ts - ts[0], 7)
        if gap:
            ts = ts[(ts < gap[0]) | (ts > gap[0] + gap[1])]
        ts = ts[ts <= dur]
        rec["ts"] = ts
        nn = ts.size
        fn = np.zeros((nn, 3))
        for c, sc in enumerate([noise["fxy_scale"], noise["fxy_scale"], 1.0]):
            s = sig * sc
            fn[:, c] = (s * math.sqrt(noise["white_share"]) * rng.standard_normal(nn)
                        + ou(rng, ts, s * math.sqrt(noise["fast_share"]), noise["fast_tau_s"])
                        + ou(rng, ts, s * math.sqrt(noise["slow_share"]), noise["slow_tau_s"]))
        rec["fnoise"] = fn
        rec["tqnoise"] = (noise["torque_sigma_nm"] * rng.standard_normal((nn, 3))
                          + np.stack([ou(rng, ts, noise["torque_sigma_nm"], 0.2) for _ in range(3)], 1))
        es = noise["encoder_sigma_m"]
        rec["pnoise"] = (es * math.sqrt(noise["encoder_white_share"]) * rng.standard_normal((nn, 3))
                         + np.stack([ou(rng, ts, es * math.sqrt(1 - noise["encoder_white_share"]),
                                        noise["encoder_tau_s"]) for _ in range(3)], 1))
        rec["vnoise"] = noise["velocity_sigma_m_per_s"] * rng.standard_normal((nn, 3))
        recs.append(rec)
        s_now += dur + (float(rng.uniform(4, 30)) if clock else 0.0)
    for r in recs:
        r["T"] = r["S"] + r["ts"]          # session clock of each sample
    allT = np.concatenate([r["T"] for r in recs])
    dst = np.concatenate([r["dstat"] for r in recs])
    contact = dst[dst > 0.5 * MM]
    base = dict(seed=seed, geo=geo, nominal_z=float(nominal_z), body=body, tilt=tilt,
                noise=noise, columns=cols, tcp_error_m=tcp_err, placement_sigma_m=place_sigma,
                session_clock=clock, recs=recs, session=[float(allT.min()), float(allT.max())],
                depth_max_m=float(np.percentile(contact, 99.5)), chosen_sites=chosen,
                site_exposure={s: 1e-9 + sum(DT * float(np.maximum(r["dstat"], 0).sum())
                                             for r in recs if r["site"] == s) for s in chosen})
    return base


# ----------------------------------------------------------------------------- effects
def draw_effect(seed, name, base, u=None):
    """Parameters of one effect from its own stream; u in [0, 1] sets its strength."""
    rng = np.random.default_rng([seed, 9000 + EFFECTS.index(name)])
    u0 = float(rng.random())
    u = u0 if u is None else u
    k, c = base["body"]["stiffness_n_per_m"], base["body"]["damping_ns_per_m"]
    dmax = base["depth_max_m"]
    p, truth, det = {"u_drawn": u0, "u": u}, {}, {}
    if name == "sensor_bias":
        bz = float(rng.choice([-1, 1]) * (0.4 + 1.6 * u))
        bxy = rng.choice([-1, 1], 2) * rng.uniform(0.05, 0.3, 2)
        p["bias"] = np.array([bxy[0], bxy[1], bz])
        p["torque_bias"] = rng.uniform(-0.02, 0.02, 3)
        truth = dict(fz_n=bz, bias_n=p["bias"].tolist())
        det = dict(form="constant offset added after sampling, also in free air",
                   torque_bias_nm=p["torque_bias"].tolist())
    elif name == "sensor_delay":
        p["delay_s"] = 0.010 + 0.050 * u
        truth = dict(delay_s=p["delay_s"])
        det = dict(form="pure transport delay F(t - delay) on fx, fy, fz (and torques) before the filter")
    elif name == "tissue_inertia":
        p["m0"], p["growth"] = 0.8 + 2.2 * u, float(rng.uniform(0.0, 0.25))
        truth = dict(moving_mass=None)     # filled by finalize (acceleration-weighted mean)
        det = dict(form="F_n += -m(d) * a_z(probe) * gate(d), m(d) = m0 * (1 + growth * min(d/10mm, 2))",
                   m0_kg=p["m0"], growth_per_10mm=p["growth"])
    elif name == "nonlinear_stiffness":
        n_target = 1.4 + 0.9 * u
        form = str(rng.choice(["cubic", "exponential", "power_blend"]))
        q = float(rng.uniform(2.0, 3.0))
        lo, ref = 2 * MM, 0.7 * dmax
        if form == "cubic":
            shape = lambda s: (lambda d: d + d ** 3 / s ** 2)
            s = bisect(lambda s: loglog_slope(shape(s), lo, dmax), 1e-4, 1.0, n_target, False)
        elif form == "exponential":
            shape = lambda s: (lambda d: s * np.expm1(d / s))
            s = bisect(lambda s: loglog_slope(shape(s), lo, dmax), 2e-4, 1.0, n_target, False)
        else:
            q = max(q, n_target + 0.4)
            shape = lambda s: (lambda d: (1 - s) * d / ref + s * (d / ref) ** q)
            s = bisect(lambda s: loglog_slope(shape(s), lo, dmax), 0.0, 1.0, n_target, True,
                       geometric=False)
        psi = shape(s)
        scale = ref / float(psi(np.array(ref)))
        p["phi"] = lambda d, psi=psi, scale=scale: scale * psi(d)
        truth = dict(exponent=loglog_slope(p["phi"], lo, dmax))
        det = dict(form={"cubic": "F = k*A*(d + d^3/s^2)", "exponential": "F = k*A*s*(exp(d/s) - 1)",
                         "power_blend": "F = k*A*((1-s)*d/ref + s*(d/ref)^q)"}[form],
                   law=form, shape_param=s, q=q, ref_depth_m=ref, A=scale, depth_range_m=[lo, dmax],
                   note="A makes F(ref) = k*ref; d is the onset-smoothed indentation")
    elif name == "viscoelastic_relaxation":
        nb = int(rng.integers(2, 4))
        taus = np.sort(np.exp(rng.uniform(np.log([0.2, 1.5, 5.0][:nb]), np.log([0.8, 4.0, 10.0][:nb]))))
        ratio = 0.3 + 0.7 * u
        wts = rng.dirichlet(np.ones(nb) * 2) * ratio
        p["branches"] = list(zip(wts.tolist(), taus.tolist()))
        truth = dict(tau_s=float(np.sum(wts * taus) / ratio), ratio=float(ratio),
                     branches=[dict(tau_s=t, ratio=w) for w, t in p["branches"]])
        det = dict(form="Prony series: F += sum_i k*r_i*(d - x_i), dx_i/dt = (d - x_i)/tau_i, states "
                        "carried across recordings (decaying through the pauses); force clamped >= 0")
    elif name == "breathing_motion":
        f = float(rng.uniform(0.18, 0.35))
        amp = (1.0 + 3.0 * u) * MM
        f_in, f_ex = float(rng.uniform(0.28, 0.38)), float(rng.uniform(0.40, 0.50))
        s0, s1 = base["session"]
        t, starts, periods, amps, z = s0 - 30 * rng.random(), [], [], [], 0.0
        while t < s1 + 1.0:
            z = 0.6 * z + 0.8 * rng.standard_normal()
            per = (1.0 / f) * math.exp(0.07 * z)
            starts.append(t)
            periods.append(per)
            amps.append(amp * float(np.clip(1 + 0.08 * rng.standard_normal(), 0.7, 1.3)))
            t += per
        ph = np.linspace(0, 1, 4001)
        wbar = float(np.mean(breath_wave(ph, f_in, f_ex)))
        used = [i for i, (a, b) in enumerate(zip(starts, periods)) if a + b > s0 and a < s1]
        p.update(starts=np.array(starts), periods=np.array(periods), amps=np.array(amps),
                 f_in=f_in, f_ex=f_ex, wbar=wbar, amp=amp)
        truth = dict(freq_hz=float(1.0 / np.mean(np.array(periods)[used])),
                     amplitude_m=float(np.mean(np.array(amps)[used])),
                     rise_m=float(2 * np.mean(np.array(amps)[used])))
        det = dict(form="surface z += profile(x,y) * (2*A_i*w(phase) - 2*A*wbar); w: raised-cosine "
                        "inhale, warped-cosine exhale, pause at end-exhale; breath periods "
                        "exp(0.07*AR1) around the mean, amplitudes +-8 %",
                   mean_rate_hz_drawn=f, inhale_fraction=f_in, exhale_fraction=f_ex,
                   pause_fraction=1 - f_in - f_ex, breaths_in_session=len(used),
                   edge_drop=base["geo"]["breath_edge_drop"],
                   profile_by_site={s: float(breath_profile(base["geo"], *site_xy(base, s)))
                                    for s in base["chosen_sites"]})
    elif name == "site_heterogeneity":
        npatch = 1 + int(rng.random() < 0.4)
        ex = np.array([base["site_exposure"][s] for s in base["chosen_sites"]])
        sites = list(rng.choice(base["chosen_sites"], npatch, replace=False, p=ex / ex.sum()))
        patches = []
        for s in sites:
            a = float(rng.choice([-1, 1]) * (0.25 + 0.35 * u))
            a = max(a, -0.6)
            cx, cy = site_xy(base, s)
            patches.append(dict(site=str(s), x=cx + rng.normal(0, 4 * MM), y=cy + rng.normal(0, 4 * MM),
                                width_m=float(rng.uniform(0.015, 0.03)), change=a))
        p["patches"] = patches
        truth = dict(stiffness_by_site={s: float(site_scale(patches, *site_xy(base, s)))
                                        for s in base["chosen_sites"]})
        det = dict(form="stiffness (elastic and relaxing) times 1 + sum change*exp(-r^2/2w^2)",
                   patches=patches)
    elif name == "sliding_friction":
        mu = 0.15 + 0.45 * u
        b = 3.0 + 37.0 * min(1.0, float(rng.random()) + 0.5 * (u - u0))
        p.update(mu=mu, b=b, static_ratio=float(rng.uniform(1.0, 1.3)),
                 stribeck_v=float(rng.uniform(1, 5) * MM), smooth_v=float(rng.uniform(0.5, 2) * MM))
        truth = dict(mu=mu, viscous_ns_per_m=b)
        det = dict(form="F_xy -= (mu*(1 + (static_ratio-1)*exp(-(v/v_s)^2))*F_n*tanh(v/v0) + b*v*tanh(F_n/0.3N)) * v_hat",
                   static_ratio=p["static_ratio"], stribeck_v_m_per_s=p["stribeck_v"],
                   smooth_v_m_per_s=p["smooth_v"], note="the none case has no tangential friction; mu is the total")
    elif name == "sensor_filter":
        fc = 15.0 * (2.0 / 15.0) ** u
        order = 1 if rng.random() < 0.5 else 2
        p.update(fc=fc, order=order)
        truth = dict(cutoff_hz=fc)
        det = dict(form="first-order low-pass" if order == 1 else
                   "critically damped second order (two equal first-order poles at fc/0.6436)",
                   order=order, cutoff_hz_minus_3db=fc)
    elif name == "bias_drift":
        total = float(rng.choice([-1, 1]) * (0.6 + 2.4 * u))
        b0 = float(rng.uniform(-0.15, 0.15))
        curved = rng.random() < 0.6
        lam = float(rng.uniform(0.3, 1.0))
        p.update(total=total, b0=b0, lam=lam if curved else None)
        truth = dict(fz_n=b0, total_n=total)
        det = dict(form="fz += b0 + total*g(s), s = share of the session elapsed (session clock), "
                        + ("g = (1-exp(-s/lam))/(1-exp(-1/lam)) (warm-up)" if curved else "g = s"),
                   lam=p["lam"], session_s=base["session"],
                   n_per_s=total / (base["session"][1] - base["session"][0]))
    elif name == "depth_dependent_damping":
        r = 0.8 + 3.2 * u
        pw, kap = float(rng.uniform(0.8, 1.6)), float(rng.uniform(0.0, 0.25))
        g = lambda d: (1 + kap) * (d / 0.01) ** pw / (1 + kap * (d / 0.01) ** pw)
        p.update(r=r, p=pw, kappa=kap, g=g)
        truth = dict(ratio_at_10mm=r, exponent=loglog_slope(g, 2 * MM, dmax))
        det = dict(form="F_n += c*r*(1+kappa)*D^p/(1+kappa*D^p) * d(delta)/dt * gate, D = delta/10mm",
                   p=pw, kappa=kap, baseline_damping_ns_per_m=c,
                   note="exponent = log-log slope of the growth over 2 mm .. deepest press")
    p["truth"], p["details"] = truth, det
    return p


def site_xy(base, s):
    cx, cy = base["geo"]["center_xy"]
    return cx + SITES[s][0], cy + SITES[s][1]


def site_scale(patches, x, y):
    out = 1.0
    for pt in patches:
        out = out + pt["change"] * np.exp(-((x - pt["x"]) ** 2 + (y - pt["y"]) ** 2) / (2 * pt["width_m"] ** 2))
    return out


def breath_wave(ph, f_in, f_ex):
    w = np.zeros_like(ph)
    a = ph < f_in
    w[a] = 0.5 - 0.5 * np.cos(math.pi * ph[a] / f_in)
    b = (ph >= f_in) & (ph < f_in + f_ex)
    w[b] = 0.5 + 0.5 * np.cos(math.pi * ((ph[b] - f_in) / f_ex) ** 0.8)
    return w


def breath(p, T):
    i = np.clip(np.searchsorted(p["starts"], T, side="right") - 1, 0, len(p["starts"]) - 1)
    ph = np.clip((T - p["starts"][i]) / p["periods"][i], 0, 1)
    return 2 * p["amps"][i] * breath_wave(ph, p["f_in"], p["f_ex"]) - 2 * p["amp"] * p["wbar"]


# ----------------------------------------------------------------------------- simulation
def simulate(base, eff):
    """Sampled recordings (dicts of arrays) for the effects in `eff` (name -> params)."""
    body = base["body"]
    k, c, s0 = body["stiffness_n_per_m"], body["damping_ns_per_m"], body["onset_m"]
    out, states, prev_end = [], None, None
    for r in base["recs"]:
        tf = r["tf"]
        h = r["hs"]
        if "breathing_motion" in eff:
            h = h + r["prof"] * breath(eff["breathing_motion"], r["S"] + tf)
        delta = h - r["z"]
        inside = delta > 0
        dpos = np.where(inside, delta, 0.0)
        gate = -np.expm1(-dpos / s0)
        de = dpos - s0 * gate                                  # smooth onset
        scale = site_scale(eff["site_heterogeneity"]["patches"], r["x"], r["y"]) \
            if "site_heterogeneity" in eff else 1.0
        phi = eff["nonlinear_stiffness"]["phi"] if "nonlinear_stiffness" in eff else (lambda d: d)
        fn = k * scale * phi(de)
        cd = c
        if "depth_dependent_damping" in eff:
            e = eff["depth_dependent_damping"]
            cd = c * (1 + e["r"] * e["g"](dpos))
        fn = fn + cd * np.gradient(delta, DT) * gate
        if "viscoelastic_relaxation" in eff:
            br = eff["viscoelastic_relaxation"]["branches"]
            if states is None:
                states = np.zeros(len(br))
            pause = r["S"] - prev_end if prev_end is not None else 0.0
            for j, (w, tau) in enumerate(br):
                xs = lowpass1(de, DT, tau, y0=states[j] * math.exp(-max(pause, 0.0) / tau))
                fn = fn + k * w * scale * (de - xs)
                states[j] = xs[-1]
        if "tissue_inertia" in eff:
            e = eff["tissue_inertia"]
            m = e["m0"] * (1 + e["growth"] * np.minimum(dpos / 0.01, 2.0))
            fn = fn - m * r["az"] * gate
        fn = np.maximum(fn, 0.0)
        F = fn[None, :] * r["nd"]
        if "sliding_friction" in eff:
            e = eff["sliding_friction"]
            sp = np.hypot(r["vx"], r["vy"])
            mu = e["mu"] * (1 + (e["static_ratio"] - 1) * np.exp(-(sp / e["stribeck_v"]) ** 2))
            mag = mu * fn * np.tanh(sp / e["smooth_v"]) + e["b"] * sp * np.tanh(fn / 0.3)
            F[0] -= mag * r["vx"] / np.maximum(sp, 1e-12)
            F[1] -= mag * r["vy"] / np.maximum(sp, 1e-12)
        # sensor chain: delay -> filter -> sampling -> bias/drift -> noise
        if "sensor_delay" in eff:
            F = np.stack([np.interp(tf - eff["sensor_delay"]["delay_s"], tf, F[i]) for i in range(3)])
        if "sensor_filter" in eff:
            e = eff["sensor_filter"]
            tau = 1 / (2 * math.pi * e["fc"]) * (0.6436 if e["order"] == 2 else 1.0)
            for _ in range(e["order"]):
                F = np.stack([lowpass1(F[i], DT, tau) for i in range(3)])
        ts = r["ts"]
        f = np.stack([np.interp(ts, tf, F[i]) for i in range(3)], 1)
        lever = -base["tilt"]["sensor_to_tip_m"] * r["a_up"]          # sensor -> tip
        tq = np.cross(np.broadcast_to(lever, f.shape), f)
        if "sensor_bias" in eff:
            f = f + eff["sensor_bias"]["bias"]
            tq = tq + eff["sensor_bias"]["torque_bias"]
        if "bias_drift" in eff:
            e = eff["bias_drift"]
            s = (r["T"] - base["session"][0]) / (base["session"][1] - base["session"][0])
            g = s if e["lam"] is None else -np.expm1(-s / e["lam"]) / -math.expm1(-1 / e["lam"])
            f[:, 2] += e["b0"] + e["total"] * g
        f = f + r["fnoise"]
        tq = tq + r["tqnoise"]
        pos = np.stack([np.interp(ts, tf, q) for q in (r["x"], r["y"], r["z"])], 1) \
            + np.array(base["tcp_error_m"]) + r["pnoise"]
        vel = np.stack([np.interp(ts, tf, q) for q in (r["vx"], r["vy"], r["vz"])], 1) + r["vnoise"]
        out.append(dict(t=ts, p=pos, f=f, v=vel, tq=tq))
        prev_end = r["S"] + r["dur"]
    return out


def rms_diff(base, a, b):
    """Time-weighted RMS of |F_a - F_b| over all recordings (gaps excluded): (vector, fz, fxy)."""
    acc = np.zeros(3)
    wsum = 0.0
    for ra, rb in zip(a, b):
        t = ra["t"]
        dt = np.diff(t, append=t[-1] + np.median(np.diff(t)))
        dt = np.where(dt > 5 * np.median(np.diff(t)), np.median(np.diff(t)), dt)
        d = ra["f"] - rb["f"]
        acc += [np.sum(dt * np.sum(d * d, 1)), np.sum(dt * d[:, 2] ** 2), np.sum(dt * np.sum(d[:, :2] ** 2, 1))]
        wsum += dt.sum()
    return np.sqrt(acc / wsum)


def finalize(base, name, p):
    if name == "tissue_inertia":
        num = den = 0.0
        for r in base["recs"]:
            d = np.maximum(r["dstat"], 0)
            w = (d > 0.5 * MM) * r["az"] ** 2
            num += np.sum(w * p["m0"] * (1 + p["growth"] * np.minimum(d / 0.01, 2)))
            den += np.sum(w)
        p["truth"]["moving_mass"] = float(num / max(den, 1e-12))
        p["details"]["note"] = "moving_mass = mean of m(d) weighted by a_z^2 over contact"
    return p


class Generator:
    def __init__(self, seed):
        self.seed = seed
        self.base = make_base(seed)
        self.none = simulate(self.base, {})
        self.cache = {}

    def effect(self, name):
        """Parameters of `name`, raised within its range until it stands >= VISIBLE sigma out."""
        if name in self.cache:
            return self.cache[name]
        sig = self.base["noise"]["fz_sigma_n"]
        p = draw_effect(self.seed, name, self.base)
        u, hist = p["u"], []
        for _ in range(6):
            p = finalize(self.base, name, draw_effect(self.seed, name, self.base, u))
            ratio = float(rms_diff(self.base, simulate(self.base, {name: p}), self.none)[0] / sig)
            hist.append(dict(u=round(u, 4), rms_sigma=round(ratio, 2)))
            if ratio >= VISIBLE or u >= 1.0:
                break
            u = min(1.0, u + 0.5 * (1 - u) + 0.1)
        p["details"]["strength"] = dict(u_drawn=p["u_drawn"], u_used=u, raised=u > p["u_drawn"],
                                        tries=hist, visible_target_sigma=VISIBLE)
        self.cache[name] = p
        return p

    def case(self, effects, outdir):
        eff = {n: self.effect(n) for n in effects}
        recs = simulate(self.base, eff) if eff else self.none
        write_dataset(self.base, recs, Path(outdir) / "dataset")
        truth = dict(generator=GENERATOR, seed=self.seed, case=case_name(effects),
                     effects={n: jsonable(eff[n]["truth"]) for n in effects},
                     effect_details={n: jsonable(eff[n]["details"]) for n in effects},
                     nuisances=nuisances(self.base))
        (Path(outdir) / "truth.json").write_text(json.dumps(truth, indent=1))
        return rms_diff(self.base, recs, self.none)


def case_name(effects):
    return "+".join(effects) if effects else "none"


def jsonable(x):
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items() if not callable(v)}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    return x


def nuisances(base):
    recs = []
    for r in base["recs"]:
        inside = r["dstat"] > 0
        recs.append(dict(file=file_name(r), site=r["site"], protocol=r["kind"],
                         motion=jsonable(r["motion"]), duration_s=r["dur"], session_start_s=r["S"],
                         rate_hz=r["rate"], stamp_jitter=r["jitter"], gap_s=r["gap"],
                         samples=int(r["ts"].size), tip_xy_m=r["xy"], free_air_height_m=r["air"],
                         probe_axis=r["a_up"].tolist(),
                         true_surface_z_at_tip_m=float(surface(base["geo"], *r["xy"])),
                         max_static_depth_m=float(r["dstat"].max()),
                         contact_share=float(inside.mean())))
    return jsonable(dict(geometry=base["geo"], nominal_surface_z_stated=base["nominal_z"],
                         site_surface_z_m={s: float(surface(base["geo"], *site_xy(base, s)))
                                           for s in base["chosen_sites"]},
                         body=dict(base["body"], form="F_n = max(0, k*(d - s0*(1-exp(-d/s0))) + "
                                   "c*dd/dt*(1-exp(-d/s0))), along 0.7*probe axis + 0.3*skin normal"),
                         tilt=base["tilt"], noise=base["noise"], columns=base["columns"],
                         tcp_error_m=base["tcp_error_m"], placement_sigma_m=base["placement_sigma_m"],
                         session_clock=base["session_clock"], session_s=base["session"],
                         depth_max_m=base["depth_max_m"], body_grid_s=DT, recordings=recs,
                         none_loglog_exponent=loglog_slope(
                             lambda d: d - base["body"]["onset_m"] * -np.expm1(-d / base["body"]["onset_m"]),
                             2 * MM, base["depth_max_m"])))


def file_name(r):
    return f"{r['index'] + 1:02d}_{r['site']}_{r['kind']}.csv"


def write_dataset(base, recs, d):
    if d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True)
    entries = []
    cols = base["columns"]
    for r, s in zip(base["recs"], recs):
        head = ["t", "px", "py", "pz", "fx", "fy", "fz"]
        data = [s["t"][:, None], s["p"], s["f"]]
        fmt = ["%.7f"] + ["%.7f"] * 3 + ["%.5f"] * 3
        if cols["velocity"]:
            head += ["vx", "vy", "vz"]
            data.append(s["v"])
            fmt += ["%.6f"] * 3
        if cols["torque"]:
            head += ["tx", "ty", "tz"]
            data.append(s["tq"])
            fmt += ["%.6f"] * 3
        np.savetxt(d / file_name(r), np.hstack(data), fmt=fmt, delimiter=",",
                   header=",".join(head), comments="")
        e = dict(file=file_name(r), site=r["site"], protocol=r["kind"])
        if base["session_clock"]:
            e["session_time_s"] = round(r["S"], 6)
        entries.append(e)
    meta = dict(format=FORMAT, description=f"hold-out session ({len(entries)} recordings)",
                nominal_surface_z=round(base["nominal_z"], 6),
                torso_center_xy=[round(v, 6) for v in base["geo"]["center_xy"]], recordings=entries)
    (d / "dataset.json").write_text(json.dumps(meta, indent=2))


# ----------------------------------------------------------------------------- matrix, check
def matrix_cases(seed):
    rng = np.random.default_rng([seed, 2000])
    pairs = [sorted([str(rng.choice(CONTACT_EFFECTS)), str(rng.choice(SENSOR_EFFECTS))]),
             sorted(["breathing_motion", str(rng.choice([e for e in EFFECTS if e != "breathing_motion"]))])]
    while len(pairs) < 4:
        a, b = sorted(rng.choice(EFFECTS, 2, replace=False).tolist())
        if [a, b] not in pairs and {a, b} != {"sensor_bias", "bias_drift"}:
            pairs.append([a, b])
    return [[]] + [[e] for e in EFFECTS] + [sorted(p, key=EFFECTS.index) for p in pairs]


def validate(d):
    """The format's reading rules as read in server/src/recordings/; a list of problems."""
    problems, segs = [], 0
    meta = json.loads((d / "dataset.json").read_text())
    if meta.get("format") != FORMAT:
        problems.append("format")
    if not all(math.isfinite(v) for v in [meta["nominal_surface_z"], *meta["torso_center_xy"]]):
        problems.append("meta not finite")
    for e in meta["recordings"]:
        if not (isinstance(e.get("site"), str) and isinstance(e.get("protocol"), str)):
            problems.append(f"{e['file']}: site/protocol")
        path = d / e["file"]
        if not path.is_file():
            problems.append(f"{e['file']}: missing")
            continue
        head = path.read_text().split("\n", 1)[0].strip().split(",")
        for col in ["t", "px", "py", "pz", "fx", "fy", "fz"]:
            if col not in head:
                problems.append(f"{e['file']}: no column {col}")
        x = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        t = x[:, head.index("t")]
        if not np.all(np.isfinite(x)):
            problems.append(f"{e['file']}: not finite")
        if np.any(np.diff(t) <= 0):
            problems.append(f"{e['file']}: time not increasing")
        med = np.sort(np.diff(t))[(t.size - 1) // 2]
        if t.size < 10 or not (50 * 0.99 <= 1 / med <= 2000 * 1.01):
            problems.append(f"{e['file']}: rate {1 / med:.1f} Hz / {t.size} samples")
        cuts = np.flatnonzero(np.diff(t) > max(5 * med, 0.05))
        pieces = np.diff(np.concatenate([[0], cuts + 1, [t.size]]))
        if np.any(pieces < 10):
            problems.append(f"{e['file']}: a segment under 10 samples")
        segs += pieces.size
    return problems, segs, len(meta["recordings"])


def read_forces(d):
    meta = json.loads((d / "dataset.json").read_text())
    out = []
    for e in meta["recordings"]:
        path = d / e["file"]
        head = path.read_text().split("\n", 1)[0].strip().split(",")
        x = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        out.append(dict(t=x[:, 0], f=x[:, [head.index(c) for c in ("fx", "fy", "fz")]]))
    return out


def check(root):
    root = Path(root)
    rows, bad = [], 0
    for case in sorted(p for p in root.iterdir() if (p / "truth.json").is_file()):
        truth = json.loads((case / "truth.json").read_text())
        problems, segs, nfiles = validate(case / "dataset")
        bad += bool(problems)
        ref = root / f"none-s{truth['seed']}"
        sig = truth["nuisances"]["noise"]["fz_sigma_n"]
        if truth["case"] == "none" or not ref.is_dir():
            rows.append((case.name, sig, None, nfiles, segs, problems))
            continue
        v = rms_diff(None, read_forces(case / "dataset"), read_forces(ref / "dataset"))
        rows.append((case.name, sig, v, nfiles, segs, problems))
    print(f"{'case':58s} {'sigma_N':>8s} {'rms|dF|_N':>10s} {'x_sigma':>8s} {'rms_dfz':>8s} "
          f"{'rms_dfxy':>8s} {'files/seg':>9s} format")
    low = 0
    for name, sig, v, nf, sg, pr in rows:
        if v is None:
            print(f"{name:58s} {sig:8.4f} {'-':>10s} {'-':>8s} {'-':>8s} {'-':>8s} {nf:4d}/{sg:<4d} "
                  f"{'ok' if not pr else '; '.join(pr)}")
            continue
        low += v[0] / sig < 3
        print(f"{name:58s} {sig:8.4f} {v[0]:10.4f} {v[0] / sig:8.1f} {v[1]:8.4f} {v[2]:8.4f} "
              f"{nf:4d}/{sg:<4d} {'ok' if not pr else '; '.join(pr)}")
    print(f"\n{len(rows)} cases; {low} effect case(s) under 3 sigma; {bad} dataset(s) failing the format rules")
    return 1 if (bad or low) else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--effects", help="comma-separated catalogue names, or none")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--matrix", action="store_true")
    ap.add_argument("--seeds", default="11,12")
    ap.add_argument("--out")
    ap.add_argument("--check", metavar="DIR")
    a = ap.parse_args()
    if a.check:
        sys.exit(check(a.check))
    if not a.out:
        ap.error("--out is required")
    t0 = time.time()
    if a.matrix:
        for seed in [int(s) for s in a.seeds.split(",") if s.strip()]:
            g = Generator(seed)
            for effects in matrix_cases(seed):
                name = f"{case_name(effects)}-s{seed}"
                v = g.case(effects, Path(a.out) / name)
                print(f"{name:60s} rms|dF| {v[0]:.3f} N ({v[0] / g.base['noise']['fz_sigma_n']:.1f} sigma)"
                      f"  [{time.time() - t0:.0f} s]", flush=True)
    else:
        if a.effects is None:
            ap.error("--effects (or --matrix / --check) is required")
        effects = [] if a.effects.strip() in ("", "none") else [e.strip() for e in a.effects.split(",")]
        unknown = [e for e in effects if e not in EFFECTS]
        if unknown:
            ap.error(f"unknown effect(s) {unknown}; known: {', '.join(EFFECTS)}")
        effects = sorted(set(effects), key=EFFECTS.index)
        g = Generator(a.seed)
        v = g.case(effects, Path(a.out))
        print(f"{case_name(effects)}-s{a.seed}: rms|dF| vs none {v[0]:.3f} N "
              f"({v[0] / g.base['noise']['fz_sigma_n']:.1f} sigma) -> {a.out}")
    print(f"generation took {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
