#!/usr/bin/env python3
"""Force along the push against the device's depth, for servo logs of the same scripted push
rendered by different force models (e.g. `gshaptics run --device replay:push.csv`).

Usage: plot_push.py OUT.png LABEL=servo_log.csv [LABEL=servo_log.csv ...]
       plot_push.py --make-push OUT.csv X Y Z_TOUCH   (a replay log for `gshaptics run --device
       replay:OUT.csv`: hold 0.5 s 5 cm above Z_TOUCH, down at 5 cm/s to 5 cm past it, hold 1 s,
       back up at 5 cm/s, hold 0.3 s; 1 kHz rows time_s,x,y,z,vx,vy,vz)
Depth is measured from the first tick with a non-zero force of the first log; the push is along -z.
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def make_push(out, x, y, z_touch):
    rows, t, dt, v = [], 0.0, 1e-3, 0.05
    z_top, z_bottom = z_touch + 0.05, z_touch - 0.05
    def hold(seconds, z):
        nonlocal t
        for _ in range(int(round(seconds / dt))):
            rows.append((t, z, 0.0))
            t += dt
    def move(z_from, z_to):
        nonlocal t
        n = int(round(abs(z_to - z_from) / (v * dt)))
        for k in range(n):
            rows.append((t, z_from + (z_to - z_from) * k / n, v if z_to > z_from else -v))
            t += dt
    hold(0.5, z_top)
    move(z_top, z_bottom)
    hold(1.0, z_bottom)
    move(z_bottom, z_top)
    hold(0.3, z_top)
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        f.write("time_s,x,y,z,vx,vy,vz\n")
        for t_, z, vz in rows:
            f.write(f"{t_:.6f},{x:.6f},{y:.6f},{z:.6f},0,0,{vz:.6f}\n")
    os.replace(tmp, out)


def main():
    if len(sys.argv) == 6 and sys.argv[1] == "--make-push":
        make_push(sys.argv[2], *map(float, sys.argv[3:]))
        return
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = sys.argv[1]
    logs = [a.split("=", 1) for a in sys.argv[2:]]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    z_touch = None
    for label, path in logs:
        d = np.genfromtxt(path, delimiter=",", names=True)
        if z_touch is None:
            touching = np.nonzero(np.abs(d["fz"]) > 1e-6)[0]
            z_touch = d["z"][touching[0]] if touching.size else d["z"].max()
        depth = (z_touch - d["z"]) * 1e3
        ax[0].plot(d["time_s"], d["fz"], lw=1, label=label)
        ax[1].plot(depth, d["fz"], lw=1, label=label)
        if "proxy_z" in d.dtype.names and label.startswith("proxy"):
            ax[0].plot(d["time_s"], (d["proxy_z"] - d["z"]) * 1e3, lw=0.8, ls="--", label=label + ": proxy above device (mm)")
    ax[0].set_xlabel("time (s)")
    ax[0].set_ylabel("F_z (N)  /  proxy gap (mm)")
    ax[1].set_xlabel("device depth past first contact (mm)")
    ax[1].set_ylabel("F_z (N), up = out of the surface")
    for a in ax:
        a.axhline(0, color="k", lw=0.5)
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("Position-controlled push 5 cm into the Truck's hood, 3 cm tool")
    fig.tight_layout()
    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=90)
    os.replace(tmp, out)


if __name__ == "__main__":
    main()
