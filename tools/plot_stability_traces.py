#!/usr/bin/env python3
"""The traced stability trials side by side (`gshaptics stability --trace-stiffness K`).

Usage: plot_stability_traces.py TRACES_CSV OUT_PNG
One column per control scheme (impedance, admittance), one row per scene, rate and round trip:
the device's height (solid) and, under admittance control, the setpoint it is commanded (the
virtual tool, dashed) against time, passivity off and on; the force sent on a second axis. A wall
the device holds shows a trace that settles; an unstable one bounces. Writes OUT_PNG through a
temporary name.
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    try:
        with open(sys.argv[1], newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"{sys.argv[1]}: cannot read the traces: {e}")
    if not rows:
        sys.exit(f"{sys.argv[1]}: no traced trials (is --trace-stiffness one of the swept stiffnesses?)")
    traces = defaultdict(lambda: {"t": [], "z": [], "sp": [], "f": []})
    for r in rows:
        key = (r["shape"], r["rate_hz"], r["delay_ms"], r["stiffness"], r["control"], r["passivity"])
        tr = traces[key]
        tr["t"].append(float(r["time_s"]))
        tr["z"].append(float(r["height_mm"]))
        tr["sp"].append(float(r["setpoint_mm"]))
        tr["f"].append(float(r["force_n"]))
    cases = sorted({k[:4] for k in traces})
    controls = sorted({k[4] for k in traces}, key=lambda c: c != "impedance")
    fig, axes = plt.subplots(len(cases), len(controls), figsize=(5.2 * len(controls), 3.2 * len(cases)),
                             squeeze=False, sharex=True)
    colors = {"0": "tab:red", "1": "tab:blue"}
    for i, case in enumerate(cases):
        shape, rate, delay, k = case
        for j, control in enumerate(controls):
            ax = axes[i][j]
            twin = ax.twinx()
            for pc in ("0", "1"):
                tr = traces.get((*case, control, pc))
                if not tr:
                    continue
                label = "passivity " + ("on" if pc == "1" else "off")
                ax.plot(tr["t"], tr["z"], lw=0.9, color=colors[pc], label=f"device height, {label}")
                if control == "admittance":
                    ax.plot(tr["t"], tr["sp"], lw=0.8, ls="--", color=colors[pc], alpha=0.7,
                            label=f"setpoint, {label}")
                twin.plot(tr["t"], tr["f"], lw=0.5, color=colors[pc], alpha=0.3)
            ax.axhline(0, color="black", lw=0.6)
            ax.set_ylabel("tool centre above the wall (mm)")
            twin.set_ylabel("force sent (N)", color="gray")
            ax.set_title(f"{shape}, {control} control, {float(k) / 1000:g} kN/m, {rate} Hz, "
                         f"{delay} ms round trip", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="upper right")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.tight_layout()
    out = sys.argv[2]
    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, out)


if __name__ == "__main__":
    main()
