#!/usr/bin/env python3
"""Figure of the stability sweep (`gshaptics stability`).

Usage: plot_stability.py TRIALS_CSV OUT_PNG
Reads the trials (stability_trials.csv) and draws, per scene and control scheme, each trial as a
point (stiffness against round-trip delay; filled: stable, open: unstable) for passivity off and
on, with the largest stable stiffness joined by a line. Writes OUT_PNG through a temporary name.
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
    with open(sys.argv[1], newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{sys.argv[1]}: no trials")
    panels = sorted({(r["shape"], r["control"]) for r in rows})
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6), squeeze=False)
    colors = {"0": "tab:red", "1": "tab:blue"}
    for ax, (shape, control) in zip(axes[0], panels):
        sel = [r for r in rows if r["shape"] == shape and r["control"] == control]
        rates = sorted({float(r["rate_hz"]) for r in sel})
        markers = dict(zip(rates, "os^vD"))
        largest = defaultdict(dict)  # (passivity, rate) -> delay -> largest stable
        for r in sel:
            key = (r["passivity"], float(r["rate_hz"]))
            d, k, stable = float(r["delay_ms"]), float(r["stiffness"]), r["stable"] == "1"
            cur = largest[key].setdefault(d, [0.0, False])
            if not cur[1]:
                if stable:
                    cur[0] = k
                else:
                    cur[1] = True
            off = 0.06 * (1 if r["passivity"] == "1" else -1)
            ax.scatter([d + off], [k], marker=markers[float(r["rate_hz"])], s=18,
                       facecolors=colors[r["passivity"]] if stable else "none",
                       edgecolors=colors[r["passivity"]], linewidths=0.8)
        for (pc, rate), by_delay in sorted(largest.items()):
            ds = sorted(by_delay)
            ks = [by_delay[d][0] for d in ds]
            ax.plot(ds, [k if k > 0 else float("nan") for k in ks], color=colors[pc],
                    linestyle="-" if rate == max(rates) else "--", linewidth=1,
                    label=f"passivity {'on' if pc == '1' else 'off'}, {rate:g} Hz")
        ax.set_yscale("log")
        ax.set_xlabel("round-trip delay, ms")
        ax.set_ylabel("coupling stiffness, N/m")
        ax.set_title(f"{shape}, {control}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
    fig.suptitle("Largest stable stiffness (filled: stable trial, open: oscillating)", fontsize=10)
    fig.tight_layout()
    out = sys.argv[2]
    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=90)
    os.replace(tmp, out)


if __name__ == "__main__":
    main()
