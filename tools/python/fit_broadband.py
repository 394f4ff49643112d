#!/usr/bin/env python3
"""An independent numpy fit of a broadband joint record given as CSV.

Reads the CSV itself (no exo importer, no MCAP), and does with numpy what
README.md and docs say `exo import` + `exo fit` do to a broadband record:

- Welch H1 of torque/angle: segments of 4096 samples (a power of two, at
  most half the record), periodic Hann window, 50 % overlap, each
  segment's mean removed; H = S_xy/S_xx with S_xy = conj(X) Y; coherence
  |S_xy|^2/(S_xx S_yy); bins 1 .. N/2 - 1.
- The excited band: not the two lowest bins, 1-100 rad/s, input power at
  least 1e-3 of its peak, coherence at least 0.6; grouped into 20 bands of
  equal width in log frequency between the first and the last kept bin;
  each band averaged with weights S_xx (frequency and H), plain means of
  coherence and S_xx.
- Each point's noise sigma = |H| sqrt((1 - g2)/(g2 n_segments)); a sigma
  below a tenth of the median is raised to it; weights 2/sigma^2 per real
  equation.
- M1 (M, B, K), M2 (M, K, H), M3 (M, B, K, H) of S = K - M w^2 + j(B w + H)
  by weighted least squares (numpy.linalg.lstsq on the rows scaled by
  sqrt(weight)), or unweighted with --unweighted; standard errors
  sqrt(s^2 (A^T W A)^-1_ii), s^2 = chi2/(2n - p); R^2 = 1 - RSS/TSS with
  TSS about the complex mean; the nested F of M1 and M2 against M3,
  (chi2_r - chi2_f)/chi2_f (2n - 4)/1.

Usage: fit_broadband.py CSV [--flip-torque] [--unweighted]
Prints one JSON object: the points and, per model, parameters, standard
errors, chi2, RSS, R^2; and the two F statistics.
"""

import argparse
import json
import sys

import numpy as np

SEGMENT = 4096
BAND_RAD_S = (1.0, 100.0)
MIN_REL_POWER = 1e-3
MIN_COHERENCE = 0.6
N_POINTS = 20
SIGMA_FLOOR = 0.1
COLS = {"M": 0, "B": 1, "K": 2, "H": 3}
MODELS = {"M1": "MBK", "M2": "MKH", "M3": "MBKH"}


def read_csv(path, flip_torque):
    d = np.genfromtxt(path, delimiter=",", names=True)
    t, x, y = d["time_s"], d["position_rad"], d["torque_nm"]
    if flip_torque:
        y = -y
    rate = (len(t) - 1) / (t[-1] - t[0])
    return x, y, rate


def welch_h1(x, y, rate, n):
    half = n // 2
    win = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)
    sxx = np.zeros(half)
    syy = np.zeros(half)
    sxy = np.zeros(half, complex)
    segs = 0
    for s in range(0, len(x) - n + 1, half):
        xs, ys = x[s : s + n], y[s : s + n]
        fx = np.fft.fft((xs - xs.mean()) * win)[:half]
        fy = np.fft.fft((ys - ys.mean()) * win)[:half]
        sxx += np.abs(fx) ** 2
        syy += np.abs(fy) ** 2
        sxy += np.conj(fx) * fy
        segs += 1
    k = np.arange(1, half)
    coh = np.clip(np.abs(sxy[k]) ** 2 / (sxx[k] * syy[k]), 0, 1)
    return {
        "omega": 2 * np.pi * k * rate / n,
        "h": sxy[k] / sxx[k],
        "coh": coh,
        "sxx": sxx[k] / segs,
        "segments": segs,
    }


def band_points(b):
    peak = b["sxx"].max()
    idx = np.arange(len(b["omega"]))
    keep = (
        (idx >= 2)
        & (b["omega"] >= BAND_RAD_S[0])
        & (b["omega"] <= BAND_RAD_S[1])
        & (b["sxx"] >= MIN_REL_POWER * peak)
        & (b["sxx"] > 0)
        & (b["coh"] >= MIN_COHERENCE)
    )
    kept = idx[keep]
    lo, hi = np.log(b["omega"][kept[0]]), np.log(b["omega"][kept[-1]]) + 1e-9
    edges = lo + (hi - lo) * np.arange(N_POINTS + 1) / N_POINTS
    pts = []
    for g in range(N_POINTS):
        l = np.log(b["omega"][kept])
        grp = kept[(l >= edges[g]) & (l < edges[g + 1])]
        if len(grp) == 0:
            continue
        w = b["sxx"][grp]
        coh = b["coh"][grp].mean()
        h = (b["h"][grp] * w).sum() / w.sum()
        rel = np.sqrt((1 - coh) / (coh * b["segments"]))
        pts.append(
            {
                "omega": float((b["omega"][grp] * w).sum() / w.sum()),
                "re": float(h.real),
                "im": float(h.imag),
                "coherence": float(coh),
                "sigma": float(rel * abs(h)),
            }
        )
    return pts


def fit(points, unweighted):
    w_ = np.array([p["omega"] for p in points])
    s = np.array([p["re"] + 1j * p["im"] for p in points])
    sig = np.array([p["sigma"] for p in points])
    n = len(points)
    if unweighted:
        wt = np.ones(n)
    else:
        sig = np.maximum(sig, SIGMA_FLOOR * np.median(sig))
        wt = 2 / sig**2
    full = np.zeros((2 * n, 4))
    full[:n, COLS["M"]] = -(w_**2)
    full[n:, COLS["B"]] = w_
    full[:n, COLS["K"]] = 1
    full[n:, COLS["H"]] = 1
    y = np.concatenate([s.real, s.imag])
    ww = np.concatenate([wt, wt])
    out = {}
    for name, terms in MODELS.items():
        a = full[:, [COLS[c] for c in terms]]
        sw = np.sqrt(ww)[:, None]
        p, *_ = np.linalg.lstsq(a * sw, y * sw[:, 0], rcond=None)
        r = y - a @ p
        chi2 = float((ww * r**2).sum())
        rss = float((r**2).sum())
        dof = 2 * n - len(terms)
        cov = chi2 / dof * np.linalg.inv(a.T @ (a * ww[:, None]))
        tss = float((np.abs(s - s.mean()) ** 2).sum())
        out[name] = {
            "params": dict(zip(terms, map(float, p))),
            "se": dict(zip(terms, map(float, np.sqrt(np.diag(cov))))),
            "chi2": chi2,
            "rss": rss,
            "r2": 1 - rss / tss,
            "dof": dof,
        }
    df_den = 2 * n - 4
    f = {
        g: (out[g[:2]]["chi2"] - out["M3"]["chi2"]) / out["M3"]["chi2"] * df_den
        for g in ("M1_M3", "M2_M3")
    }
    return out, f


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("csv")
    ap.add_argument("--flip-torque", action="store_true")
    ap.add_argument("--unweighted", action="store_true")
    a = ap.parse_args()
    x, y, rate = read_csv(a.csv, a.flip_torque)
    n = max(16, min(SEGMENT, (1 << (len(x) - 1).bit_length()) // 2))
    pts = band_points(welch_h1(x, y, rate, n))
    models, f = fit(pts, a.unweighted)
    json.dump({"rate_hz": rate, "points": pts, "models": models, "f": f}, sys.stdout)
    print()


if __name__ == "__main__":
    main()
