#!/usr/bin/python3
"""Draws the paper's Fig. 5 for a gshaptics probe run.

Usage: plot_probe_run.py probe_log.csv summary.json out.png

Rows: (1) broad-phase candidates, pre-filtered and colliding Gaussians; (2) rendered force
x/y/z in the world frame; (3) force of the (simulated) user's hand; (4) collision-query time;
and for a real-time run (servo_log.csv of `gshaptics run`) a fifth row: servo tick jitter with
the ticks that held a stale result or faded marked. Under admittance control (--control
admittance) the user force row is the force/torque sensor's reading and a last row shows the
virtual tool (the setpoint commanded) against the device's measured position.
Vertical lines mark the start of each contact episode (t_a, t_b, ...); for a probe run
(simulate) the planned sites are marked on the force row: S1, S2, ... (green: touched, red: missed).
With the proxy (god-object) renderer the first row shows the Gaussians holding the proxy instead
of the paper's pre-filter and K_min counts.
The PNG is written to a temporary name and renamed, so a failed run never leaves half a file.
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main(argv):
    if len(argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    csv_path, summary_path, png_path = argv[1:]
    try:
        data = np.genfromtxt(csv_path, delimiter=",", names=True)
    except (OSError, ValueError) as e:
        print(f"{csv_path}: cannot read the tick log: {e}", file=sys.stderr)
        return 1
    if data.size == 0:
        print(f"{csv_path}: the tick log has no rows", file=sys.stderr)
        return 1
    with open(summary_path) as f:
        summary = json.load(f)
    t = data["time_s"]
    realtime = "jitter_us" in data.dtype.names
    has_proxy = "proxy_x" in data.dtype.names
    has_energy = "energy_j" in data.dtype.names
    proxy_row = 5 if realtime else 4
    energy_row = proxy_row + (1 if has_proxy else 0)
    torque_row = energy_row + (1 if has_energy else 0)
    # Compound tools: the torque sent about the tool centre point (a sphere's is zero: no row).
    has_torque = all(c in data.dtype.names for c in ("tx", "ty", "tz")) and bool(
        np.any(np.abs(np.stack([data["tx"], data["ty"], data["tz"]])) > 0))
    admittance = all(c in data.dtype.names for c in ("setpoint_x", "setpoint_y", "setpoint_z"))
    admittance_row = torque_row + (1 if has_torque else 0)
    rows = admittance_row + (1 if admittance else 0)
    fig, ax = plt.subplots(rows, 1, figsize=(11, 2.4 * rows + 0.4), sharex=True)
    proxy = summary.get("renderer", "proxy" if has_proxy else "paper") == "proxy"
    ax[0].plot(t, data["candidates"], lw=0.8, label="broad-phase candidates")
    if proxy:
        # The proxy (god-object) runs no pre-filter or K_min per tick: its contacts are the
        # Gaussians that hold it (its blockers), a handful even where many overlap the device's tool.
        ax[0].plot(t, data["contacts"], lw=1.0, label="Gaussians holding the proxy")
    else:
        ax[0].plot(t, data["prefiltered"], lw=0.8, label="after sphere pre-filter (eq. 4)")
        ax[0].plot(t, data["contacts"], lw=1.0, label="colliding (K_min > 0)")
    ax[0].set_yscale("symlog", linthresh=10)
    ax[0].set_ylabel("Gaussians")
    for name, lab in (("fx", "x"), ("fy", "y"), ("fz", "z")):
        ax[1].plot(t, data[name], lw=0.9, label=f"F_{lab}")
    ax[1].set_ylabel("rendered force (N)")
    for name, lab in (("user_fx", "x"), ("user_fy", "y"), ("user_fz", "z")):
        ax[2].plot(t, data[name], lw=0.9, label=f"F_user,{lab}")
    ax[2].set_ylabel("sensor: user force (N)" if admittance else "user force (N)")
    ax[3].plot(t, data["query_us"], lw=0.6, color="tab:purple", label="collision query")
    ax[3].set_yscale("log")
    ax[3].axhline(1000, color="red", ls="--", lw=0.8, label="1 ms servo period")
    ax[3].set_ylabel("query time (us)")
    ax[-1].set_xlabel("time (s)")
    if realtime:
        rt = summary.get("runtime", {})
        period_us = 1e6 / rt.get("rate_hz", 1000)
        ax[4].plot(t, np.maximum(data["jitter_us"], 0.01), lw=0.5, color="tab:gray", label="tick jitter")
        held = data["held"] > 0
        fading = data["fading"] > 0
        if held.any():
            ax[4].plot(t[held], np.maximum(data["jitter_us"][held], 0.01), "o", ms=2.5,
                       color="tab:orange", label=f"held a stale result ({int(held.sum())} ticks)")
        if fading.any():
            ax[4].plot(t[fading], np.maximum(data["jitter_us"][fading], 0.01), "x", ms=3,
                       color="tab:red", label=f"fading/faded ({int(fading.sum())} ticks)")
        ax[4].axhline(period_us, color="red", ls="--", lw=0.8, label="one servo period")
        ax[4].set_yscale("log")
        ax[4].set_ylabel("jitter (us)")
        j = rt.get("jitter_us", {})
        ax[4].set_title(f"{rt.get('achieved_rate_hz', 0):.1f} Hz achieved, jitter p99 "
                        f"{j.get('p99', 0):.1f} us, {rt.get('deadline_misses', 0)} deadline misses, "
                        f"{rt.get('stale_ticks', 0)} stale ticks", fontsize=9, loc="right")
    if has_proxy:
        # Proxy (god-object): how far the force model holds the tool from the device, and on how
        # many constraint planes.
        gap = np.sqrt((data["proxy_x"] - data["x"]) ** 2 + (data["proxy_y"] - data["y"]) ** 2 +
                      (data["proxy_z"] - data["z"]) ** 2)
        ax[proxy_row].plot(t, gap * 1e3, lw=0.9, color="tab:green", label="proxy to device distance")
        ax[proxy_row].set_ylabel("proxy gap (mm)")
        twin = ax[proxy_row].twinx()
        twin.plot(t, data["constraints"], lw=0.6, color="tab:gray", alpha=0.6, label="constraint planes")
        twin.set_ylim(-0.2, 3.5)
        twin.set_ylabel("constraints")
        ax[proxy_row].legend(loc="upper left", fontsize=8)
    if has_energy:
        # Passivity observer (Hannaford & Ryu 2002): energy into the scene since the last release
        # (< 0: the scene gave back more than it took), and the controller's damping.
        e = ax[energy_row]
        e.plot(t, data["energy_j"] * 1e3, lw=0.9, color="tab:blue", label="observed energy E")
        e.axhline(0, color="black", lw=0.6)
        e.set_ylabel("energy (mJ)")
        twin = e.twinx()
        twin.plot(t, data["pc_damping"], lw=0.6, color="tab:red", alpha=0.7, label="controller damping")
        twin.set_ylabel("damping (N s/m)")
        pc = summary.get("passivity", summary.get("runtime", {}))
        ticks = pc.get("passivity_ticks", pc.get("ticks", 0))  # run summaries: runtime.passivity_ticks
        e.set_title(f"passivity controller acted on {ticks} ticks", fontsize=9, loc="right")
    if has_torque:
        for name, lab in (("tx", "x"), ("ty", "y"), ("tz", "z")):
            ax[torque_row].plot(t, data[name], lw=0.9, label=f"tau_{lab}")
        ax[torque_row].set_ylabel("torque sent (N m)")
        tau = np.sqrt(data["tx"] ** 2 + data["ty"] ** 2 + data["tz"] ** 2)
        ax[torque_row].set_title(f"peak {tau.max():.3f} N m about the tool centre point", fontsize=9, loc="right")
    if admittance:
        # Admittance control: the device follows the virtual tool through its position servo; the
        # row shows both heights (the approach axis is the world's up) and the tracking error.
        a = ax[admittance_row]
        a.plot(t, data["setpoint_z"] * 1e3, lw=0.9, color="tab:blue", label="virtual tool (setpoint) z")
        a.plot(t, data["z"] * 1e3, lw=0.9, ls="--", color="tab:orange", label="device z (measured)")
        a.set_ylabel("height (mm)")
        err = np.sqrt((data["setpoint_x"] - data["x"]) ** 2 + (data["setpoint_y"] - data["y"]) ** 2 +
                      (data["setpoint_z"] - data["z"]) ** 2)
        twin = a.twinx()
        twin.plot(t, err * 1e3, lw=0.6, color="tab:red", alpha=0.7, label="tracking error")
        twin.set_ylabel("tracking error (mm)")
        a.set_title(f"admittance control: tracking error p99 {np.percentile(err, 99) * 1e3:.3f} mm, "
                    f"max {err.max() * 1e3:.3f} mm", fontsize=9, loc="right")
    q = summary.get("query_us", {})
    ax[3].set_title(f"p50 {q.get('p50', 0):.1f} us, p99 {q.get('p99', 0):.1f} us, "
                    f"max {q.get('max', 0):.1f} us", fontsize=9, loc="right")
    for i, ep in enumerate(summary.get("episodes", [])):
        label = "t_" + (chr(ord("a") + i) if i < 26 else str(i))
        for a in ax:
            a.axvline(ep["t_start"], color="gray", ls=":", lw=0.8)
        ax[0].annotate(label, (ep["t_start"], 1), xycoords=("data", "axes fraction"),
                       xytext=(2, -10), textcoords="offset points", fontsize=8)
    # The planned probe sites (simulate): a green triangle where the tool touched, a red cross
    # where it missed, at the planned touch time.
    for i, site in enumerate(summary.get("sites", [])):
        if "touched" not in site:
            continue
        touched = site["touched"]
        ax[1].plot([site["t_touch"]], [1.0], transform=ax[1].get_xaxis_transform(), clip_on=False,
                   marker="v" if touched else "x", ms=7, color="tab:green" if touched else "tab:red",
                   label=None)
        ax[1].annotate(f"S{i + 1}" + ("" if touched else " missed"), (site["t_touch"], 1.0),
                       xycoords=("data", "axes fraction"), xytext=(4, 2), textcoords="offset points",
                       fontsize=7, color="tab:green" if touched else "tab:red")
    for a in ax:
        a.grid(alpha=0.3)
        a.legend(loc="upper left", fontsize=7, ncol=3)
    scene = os.path.basename(summary.get("scene", ""))
    kind = (f"real-time run ({summary.get('mode', '')}, {summary.get('runtime', {}).get('rate_hz', 0):.0f} Hz)"
            if realtime else "probe run")
    fig.suptitle(f"gshaptics {kind}: {scene}, {summary.get('gaussians_kept', '?')} Gaussians "
                 f"after the opacity filter, tool radius {summary.get('tool_radius', 0):.3g}")
    fig.tight_layout()
    tmp = png_path + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, png_path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
