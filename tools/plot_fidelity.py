#!/usr/bin/env python3
"""Figures of the haptic fidelity benchmark (`gshaptics fidelity`).

Usage: plot_fidelity.py DATA_DIR OUT_DIR MODEL
Reads press_curves.csv, slide_curves.csv, push_curves.csv and press_directions.csv from DATA_DIR
and writes fidelity_press.png, fidelity_direction.png, fidelity_slide.png and fidelity_push.png
into OUT_DIR (each written to a temporary name, then renamed).
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def curves(rows):
    """(shape, spacing, tool) -> (x, |F|, F_n) lists."""
    out = defaultdict(lambda: ([], [], []))
    for r in rows:
        key = (r["shape"], float(r["spacing_mm"]), float(r["tool_mm"]))
        out[key][0].append(float(r["x_mm"]))
        out[key][1].append(float(r["force_n"]))
        out[key][2].append(float(r["f_normal_n"]))
    return out


def save(fig, out_dir, name):
    path = os.path.join(out_dir, name)
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=90)
    plt.close(fig)
    os.replace(tmp, path)


def panels(data, title, xlabel, ylabel, component, out_dir, name, model, xmin=None):
    shapes = sorted({k[0] for k in data})
    if not shapes:
        return
    cols = min(4, len(shapes))
    rows = (len(shapes) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3 * rows), squeeze=False)
    for ax, shape in zip(axes.flat, shapes):
        for (s, spacing, tool), c in sorted(data.items()):
            if s != shape:
                continue
            ax.plot(c[0], c[component], lw=1, label=f"{spacing:g} mm, tool {tool:g} mm")
        ax.set_title(shape)
        if xmin is not None:
            ax.set_xlim(left=xmin)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.axhline(0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[len(shapes):]:
        ax.axis("off")
    fig.suptitle(f"{title} (force model: {model})")
    fig.tight_layout()
    save(fig, out_dir, name)


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    data_dir, out_dir, model = sys.argv[1:]
    panels(curves(read(os.path.join(data_dir, "press_curves.csv"))), "Press: |F| over penetration",
           "delta (mm)", "|F| (N)", 1, out_dir, "fidelity_press.png", model, xmin=-3)
    panels(curves(read(os.path.join(data_dir, "slide_curves.csv"))), "Slide at 2 mm: |F| along the path",
           "path (mm)", "|F| (N)", 1, out_dir, "fidelity_slide.png", model)
    panels(curves(read(os.path.join(data_dir, "push_curves.csv"))),
           "Push-through: force along the outward normal", "delta (mm)", "F . n (N)", 2, out_dir,
           "fidelity_push.png", model, xmin=-3)
    hist = defaultdict(lambda: [0] * 180)
    for r in read(os.path.join(data_dir, "press_directions.csv")):
        hist[r["shape"]][int(r["bin_deg"])] += int(r["count"])
    fig, ax = plt.subplots(figsize=(8, 4))
    for shape, counts in sorted(hist.items()):
        total = max(1, sum(counts))
        ax.step(range(180), [c / total for c in counts], where="post", label=shape)
    ax.set_yscale("log")
    ax.set_xlabel("direction error (deg): angle between F and the true normal cone")
    ax.set_ylabel("share of ticks with |F| >= 0.1 N")
    ax.set_title(f"Press direction errors (force model: {model})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save(fig, out_dir, "fidelity_direction.png")


if __name__ == "__main__":
    main()
