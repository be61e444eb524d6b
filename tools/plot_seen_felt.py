#!/usr/bin/env python3
"""Figure of the seen-against-felt benchmark (`gshaptics seen-felt`).

Usage: plot_seen_felt.py RAYS_CSV OUT_PNG
Reads the rays (seen_felt_rays.csv) and draws two panels: per scene and configuration, where the
proxy rested (felt - seen) and where the force began (onset - seen), both in tool radii R, one point
per ray, with the targets (felt within +0.5 R, through beyond +1 R, onset no earlier than -1 R)
shaded. Rays with no force are drawn as crosses at the felt panel's top. Where a sphere's onset
over its whole shadow (onset_shadow_minus_seen) differs from its centre line's, it is drawn as a
circle. Rays in a slot narrower than the tool (slot = 1) show only when they felt nothing.
Writes OUT_PNG through a temporary name.
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def configurations(rows):
    order = []
    for r in rows:
        key = (r["scene"], r["direction"], float(r["tool_fraction"]))
        if key not in order:
            order.append(key)
    return order


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1], newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{sys.argv[1]}: no rays")
    keys = configurations(rows)
    fig, axes = plt.subplots(2, 1, figsize=(max(6.0, 0.32 * len(keys) + 2), 6.4), sharex=True)
    colors = {"vertical": "tab:blue", "around": "tab:orange"}
    for x, key in enumerate(keys):
        every = [r for r in rows if (r["scene"], r["direction"], float(r["tool_fraction"])) == key]
        # (rays in a slot are scored for through and no force only; older CSVs have no such column)
        ray = [r for r in every if r.get("slot", "0") == "0"]
        felt = [float(r["felt_minus_seen"]) for r in ray if r["no_force"] == "0"]
        none = [float(r["felt_minus_seen"]) for r in every if r["no_force"] == "1"]
        onset = [float(r["onset_minus_seen"]) for r in ray if not math.isnan(float(r["onset_minus_seen"]))]
        # a sphere's onset over its whole shadow, where it differs from its centre line's (older
        # CSVs have no such column)
        shadow = [float(r["onset_shadow_minus_seen"]) for r in ray
                  if not math.isnan(float(r.get("onset_shadow_minus_seen", "nan")))
                  and abs(float(r["onset_shadow_minus_seen"]) - float(r["onset_minus_seen"])) > 0.05]
        c = colors.get(key[1], "gray")
        axes[0].scatter([x] * len(felt), felt, s=9, color=c, alpha=0.7)
        axes[0].scatter([x] * len(none), [min(v, 4.4) for v in none], s=16, color="black", marker="x")
        axes[1].scatter([x] * len(onset), [max(v, -20) for v in onset], s=9, color=c, alpha=0.7)
        axes[1].scatter([x] * len(shadow), [max(v, -20) for v in shadow], s=22, facecolors="none",
                        edgecolors="black", linewidths=0.7, label="over the tool's shadow" if shadow else None)
    axes[0].axhspan(-0.5, 0.5, color="tab:green", alpha=0.12)
    axes[0].axhline(1.0, color="tab:red", lw=0.8, ls="--")
    axes[0].set_ylabel("felt - seen, R")
    axes[0].set_title("Where the proxy rests (x: no force; above the dashed line: through)", fontsize=9)
    axes[1].axhspan(-1.0, 0.5, color="tab:green", alpha=0.12)
    axes[1].set_ylabel("onset - seen, R (clipped at -20)")
    axes[1].set_title("Where the force starts (below the band: an invisible wall). Circles: the sphere's "
                      "whole shadow, its deepest line past its seen surface (above 0: some point of the tool "
                      "was past what the eye sees beside the centre line)", fontsize=9)
    handles, names = axes[1].get_legend_handles_labels()
    if handles:
        axes[1].legend(handles[:1], names[:1], fontsize=7, loc="lower right")
    labels = [f"{s.split('.')[0]} {d[0]} {f * 100:g}%" for s, d, f in keys]
    axes[1].set_xticks(range(len(keys)))
    axes[1].set_xticklabels(labels, rotation=90, fontsize=7)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    out = sys.argv[2]
    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=90)
    os.replace(tmp, out)


if __name__ == "__main__":
    main()
