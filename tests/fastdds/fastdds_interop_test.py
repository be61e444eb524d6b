#!/usr/bin/python3
"""ROS 2 wire compatibility across two DDS vendors: a Fast DDS participant (fastdds_interop,
types from fastddsgen) publishes geometry_msgs/PoseStamped to `gshaptics node --ros2` (Cyclone
DDS) arriving from above at a pose in contact with the bundled Truck, and must read back WrenchStamped with a contact
force, zero force after its poses stop (the node's watchdog), and MarkerArrays with the tool and
the touched Gaussians. The contact pose comes from `gshaptics poses` + `gshaptics query`.

Usage: fastdds_interop_test.py PATH/TO/gshaptics PATH/TO/fastdds_interop REPO
"""
import json
import os
import signal
import subprocess
import sys
import tempfile
import unittest

EXE = FASTDDS = REPO = None


def contact_pose():
    """A tool pose on the registered Truck (the node's default world) that touches Gaussians."""
    scene = os.path.join(REPO, "data", "truck.splat")
    reg = os.path.join(REPO, "data", "truck.registration.json")
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
        f.write(subprocess.run([EXE, "poses", scene, "--registration", reg, "--count", "20", "--seed", "3"],
                               capture_output=True, text=True, check=True, timeout=120).stdout)
    out = subprocess.run([EXE, "query", scene, "--registration", reg, "--poses", f.name],
                         capture_output=True, text=True, check=True, timeout=120).stdout.splitlines()
    poses = [line.split() for line in open(f.name) if line.strip() and not line.startswith("#")]
    os.unlink(f.name)
    best = max(range(len(out)), key=lambda i: len(json.loads(out[i])["contacts"]))
    return [float(v) for v in poses[best][:3]], float(poses[best][3])


class FastDdsToCyclone(unittest.TestCase):
    def test_pose_in_wrench_and_markers_out(self):
        centre, radius = contact_pose()
        domain = str(150 + os.getpid() % 50)
        d = tempfile.mkdtemp()
        node = subprocess.Popen([EXE, "node", "--ros2", "--domain", domain, "--tool-radius", repr(radius),
                                 "--quiet", "--no-plot", "--out", d],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            line = ""
            while "ready" not in line:
                line = node.stdout.readline()
                if line == "":
                    self.fail("gshaptics node ended before it was ready: " + node.stderr.read())
            # The tool arrives from 5 radii above (z up) over a second: the seen solid, like any
            # god-object, holds a tool that comes to it, not one placed inside it.
            above = [centre[0], centre[1], centre[2] + 5 * radius]
            p = subprocess.run([FASTDDS, "--domain", domain, "--pose", ",".join(map(repr, centre)),
                                "--from", ",".join(map(repr, above)), "--seconds", "3"],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            seen = json.loads(p.stdout.strip().splitlines()[-1])
        finally:
            node.send_signal(signal.SIGINT)
            out, err = node.communicate(timeout=60)
        self.assertEqual(node.returncode, 0, err)
        print(json.dumps(seen), file=sys.stderr)
        self.assertTrue(seen["matched"], "Fast DDS and Cyclone DDS did not discover each other")
        self.assertGreater(seen["poses_sent"], 1000)
        self.assertGreater(seen["wrenches"], 100)
        self.assertGreater(seen["max_force"], 0.1)          # the tool pressed into the Truck
        self.assertGreater(seen["wrenches_after_stop"], 0)
        self.assertEqual(seen["last_force"], 0.0)           # the node's watchdog after the poses stop
        self.assertNotEqual(seen["wrench_frame"], "")
        self.assertGreater(seen["marker_arrays"], 5)
        self.assertGreaterEqual(seen["max_markers"], 2)     # the tool and the touched Gaussians
        summary = json.load(open(os.path.join(d, "run_summary.json")))
        ros2 = summary["ros2"]
        self.assertGreater(ros2["poses_received"], 1000)
        self.assertEqual(ros2["poses_dropped"], 0)
        self.assertEqual(ros2["qos_incompatible"], 0)


if __name__ == "__main__":
    EXE, FASTDDS, REPO = sys.argv[1], sys.argv[2], sys.argv[3]
    unittest.main(argv=[sys.argv[0], "-v"])
