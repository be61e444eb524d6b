#!/usr/bin/python3
"""The paper's two-machine split on one machine: `gshaptics node --ros2` and
`gshaptics device-sim --ros2` as two processes over loopback DDS run the probe trajectory on the
bundled Truck; contacts and forces must match the in-process simulation (`gshaptics simulate`)
within a tick's latency, and no pose may be lost at 1 kHz.

Usage: ros2_test.py PATH/TO/gshaptics   (CYCLONEDDS_URI should point at the loopback config)
"""
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest

EXE = None
SITES = "2"


def load_json(path):
    with open(path) as f:
        return json.load(f)


def episodes(rows, force_cols, t_col="time_s", gap=0.1):
    """Contact episodes of a log by |F| > 0: [start, end, peak |F|]."""
    eps, last = [], -1.0
    for r in rows:
        f = sum(float(r[c]) ** 2 for c in force_cols) ** 0.5
        t = float(r[t_col])
        if f > 0:
            if not eps or t - last > gap:
                eps.append([t, t, 0.0])
            eps[-1][1] = t
            eps[-1][2] = max(eps[-1][2], f)
            last = t
    return eps


class TwoProcesses(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp()
        domain = str(100 + os.getpid() % 100)
        common = ["--ros2", "--domain", domain, "--reliable", "--depth", "64"]
        cls.node = subprocess.Popen(
            [EXE, "node", *common, "--quiet", "--no-plot", "--out", os.path.join(cls.dir, "node")],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = ""
        while "ready" not in line:
            line = cls.node.stdout.readline()
            if line == "":
                raise AssertionError("gshaptics node ended before it was ready: " + cls.node.stderr.read())
        cls.dev = subprocess.run(
            [EXE, "device-sim", *common, "--sites", SITES, "--quiet", "--out", os.path.join(cls.dir, "dev")],
            capture_output=True, text=True, timeout=300)
        time.sleep(0.5)
        cls.node.send_signal(signal.SIGINT)
        cls.node_out, cls.node_err = cls.node.communicate(timeout=60)
        cls.sim = subprocess.run(
            [EXE, "simulate", "--sites", SITES, "--quiet", "--no-plot", "--out", os.path.join(cls.dir, "sim")],
            capture_output=True, text=True, timeout=300)

    def test_processes_exit_cleanly(self):
        self.assertEqual(self.dev.returncode, 0, self.dev.stderr)
        self.assertEqual(self.node.returncode, 0, self.node_err)
        self.assertEqual(self.sim.returncode, 0, self.sim.stderr)

    def test_no_pose_lost(self):
        dev = load_json(os.path.join(self.dir, "dev", "device_summary.json"))
        node = load_json(os.path.join(self.dir, "node", "run_summary.json"))
        self.assertGreater(dev["poses_sent"], 10000)
        self.assertEqual(node["ros2"]["poses_received"], dev["poses_sent"])
        self.assertEqual(node["ros2"]["poses_dropped"], 0)
        self.assertEqual(node["ros2"]["pose_publishers"], 1)
        print(f"\nround trip pose -> wrench: {dev['latency_us']}", file=sys.stderr)

    def test_forces_match_the_in_process_simulation(self):
        with open(os.path.join(self.dir, "dev", "device_log.csv")) as f:
            dev_eps = episodes(list(csv.DictReader(f)), ("fx", "fy", "fz"))
        sim_eps = load_json(os.path.join(self.dir, "sim", "summary.json"))["episodes"]
        self.assertEqual(len(dev_eps), len(sim_eps), f"{dev_eps} vs {sim_eps}")
        for (t0, t1, peak), s in zip(dev_eps, sim_eps):
            # Contact starts within a few ticks (the round trip adds about one period).
            self.assertAlmostEqual(t0, s["t_start"], delta=0.02)
            self.assertAlmostEqual(peak, s["peak_force"], delta=0.1 * s["peak_force"] + 0.2)

    def test_node_saw_the_contacts(self):
        node = load_json(os.path.join(self.dir, "node", "run_summary.json"))
        sim = load_json(os.path.join(self.dir, "sim", "summary.json"))
        peaks = [e["peak_contacts"] for e in node["episodes"]]
        self.assertEqual(len(peaks), len(sim["episodes"]))
        for p, s in zip(peaks, sim["episodes"]):
            self.assertAlmostEqual(p, s["peak_contacts"], delta=0.15 * s["peak_contacts"] + 5)
        self.assertGreater(node["ros2"]["markers_published"], 10)


if __name__ == "__main__":
    EXE = sys.argv[1]
    unittest.main(argv=[sys.argv[0], "-v"])
