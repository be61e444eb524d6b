"""Your own haptic loop on gshaptics from Python: the bundled Truck, a 3 cm spherical tool lowered
onto its roof at 10 cm/s, one collision query plus the paper's force model (eq. 7-11) per 1 kHz
tick until the first touch.

Usage: PYTHONPATH=build/python /usr/bin/python3 examples/embed.py [DATA_DIR]
"""
import os
import sys

import numpy as np

import gshaptics

data = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "data")
scene = gshaptics.Scene.load(os.path.join(data, "truck.splat"))
world = gshaptics.CollisionWorld(scene, registration=os.path.join(data, "truck.registration.json"))
force_model = gshaptics.ForceModel(gshaptics.ForceParams())
dt, radius, velocity = 1e-3, 0.03, np.array([0.0, 0.0, -0.1])
tool = np.array([0.0, 0.0, world.bounds[1][2] + radius])  # above the truck's roof
for tick in range(60000):  # your device's pose here
    hit = world.query(tool, (radius, radius, radius))
    force = force_model.update(hit, tool, velocity, dt)
    if len(hit) > 0:  # send `force` (N, world frame) to your device here; we stop at the first touch
        print(f"t = {tick * dt:.3f} s: tool at {np.round(tool, 3)} m touches {len(hit)} Gaussians, "
              f"force {np.round(force, 2)} N")
        sys.exit(0 if force[2] > 0 else 1)
    tool = tool + velocity * dt
print("no contact")
sys.exit(1)
