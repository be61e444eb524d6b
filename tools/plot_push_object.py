#!/usr/bin/env python3
"""The push scenario of `gshaptics simulate --scenario push`: the box's path, the contact force on
it and the friction it felt, against Coulomb's mu m g.

Usage: plot_push_object.py push_log.csv summary.json OUT.png
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def moving_mean(x, n):
    if len(x) < n:
        return x
    return np.convolve(x, np.ones(n) / n, mode="same")


def main(argv):
    if len(argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    csv_path, summary_path, out = argv[1:]
    try:
        d = np.genfromtxt(csv_path, delimiter=",", names=True)
        with open(summary_path) as f:
            s = json.load(f)
    except (OSError, ValueError) as e:
        print(f"plot_push_object.py: {e}", file=sys.stderr)
        return 1
    if d.size < 3:
        print(f"plot_push_object.py: {csv_path}: fewer than 3 ticks", file=sys.stderr)
        return 1
    t = d["t_s"]
    mass, mu = s["box"]["mass_kg"], s["box"]["friction"]
    expected = s["friction_expected_N"]
    # The friction the box felt while it slid: the push less m a (a over 20 ms).
    dt = np.gradient(t)
    a = np.gradient(moving_mean(d["box_vx"], 20)) / np.where(dt > 0, dt, 1)
    sliding = (d["box_vx"] > 0.02) & (np.roll(d["box_vx"], 1) > 0.02)
    friction = np.where(sliding, d["push_x"] - mass * a, np.nan)

    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    ax[0].plot(t, 100 * d["hand_x"], label="hand target", color="0.6", ls="--")
    ax[0].plot(t, 100 * d["device_x"], label="tool (device)", color="C0")
    ax[0].plot(t, 100 * d["box_x"], label="box centre", color="C3")
    ax[0].set_ylabel("x, cm")
    ax[0].set_title(f"push scenario: {mass:g} kg box, mu {mu:g}; travelled {100 * s['travelled_m']:.1f} cm, "
                    f"deepest K_min {s['deepest_k_min']:.2g}")
    ax[0].legend(loc="upper left", fontsize=8)
    ax[1].plot(t, d["push_x"], color="C1", label="push on the box, x")
    ax[1].plot(t, np.hypot(d["push_y"], d["push_z"]), color="C2", lw=0.8, label="push, y-z")
    ax[1].axhline(expected, color="k", lw=0.8, ls=":", label="mu m g")
    ax[1].set_ylabel("force, N")
    ax[1].legend(loc="upper left", fontsize=8)
    ax[2].plot(t, friction, color="C4", lw=0.8, label="push - m a while sliding")
    ax[2].axhline(expected, color="k", lw=0.8, ls=":", label=f"mu m g = {expected:.3f} N")
    felt = s["friction_felt_N"]
    ax[2].axhline(felt, color="C4", lw=1.2, ls="--", label=f"mean felt {felt:.3f} N")
    ax[2].set_ylabel("friction, N")
    ax[2].set_xlabel("t, s")
    if np.isfinite(friction).any():
        lo, hi = np.nanpercentile(friction, [2, 98])
        ax[2].set_ylim(min(lo, expected) - 0.2 * expected, max(hi, expected) + 0.2 * expected)
    ax[2].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
