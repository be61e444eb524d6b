#!/usr/bin/python3
"""Load the bundled Truck, run the simulated probe trajectory through the gshaptics Python
module, and plot contacts and force. Usage (after scripts/setup.sh):

    PYTHONPATH=build/python /usr/bin/python3 python/examples/probe_truck.py [out.png]
"""
import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gshaptics  # noqa: E402

parser = argparse.ArgumentParser(description="Probe the bundled Truck through the gshaptics Python module "
                                             "and plot contacts and force.")
parser.add_argument("out", nargs="?", default="probe_truck_python.png", help="the figure to write (PNG)")
args = parser.parse_args()

here = os.path.dirname(os.path.abspath(__file__))
data = os.path.join(here, "..", "..", "data")
scene = gshaptics.Scene.load(os.path.join(data, "truck.splat"))
world = gshaptics.CollisionWorld(scene, min_opacity=0.2,
                                 registration=os.path.join(data, "truck.registration.json"))
print(f"{len(scene)} Gaussians loaded, {len(world)} kept after the opacity filter")

run = world.run_probe(sites=7, seed=1, tool_radius=0.075)
t, force = run["time"], run["force"]
print(f"{len(t)} ticks; query time p50 {np.median(run['query_us']):.1f} us, "
      f"p99 {np.percentile(run['query_us'], 99):.1f} us; peak force {np.linalg.norm(force, axis=1).max():.1f} N")

fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
ax[0].plot(t, run["candidates"], lw=0.8, label="candidates")
ax[0].plot(t, run["contacts"], lw=0.8, label="contacts")
ax[0].set_yscale("symlog", linthresh=10)
ax[0].set_ylabel("Gaussians")
ax[0].legend(loc="upper left")
for k, name in enumerate("xyz"):
    ax[1].plot(t, force[:, k], lw=0.8, label=f"F_{name}")
ax[1].plot(t, np.linalg.norm(force, axis=1), "k", lw=0.6, label="|F|")
ax[1].set_ylabel("force (N)")
ax[1].set_xlabel("time (s)")
ax[1].legend(loc="upper left")
for tt in run["site_touch_times"]:
    for a in ax:
        a.axvline(tt, color="gray", ls=":", lw=0.8)
out = args.out
fig.tight_layout()
fig.savefig(out, dpi=100)
print(f"figure: {out}")
