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


# Contact episodes closer than this are one, on every side of a comparison: the summaries merge
# those under 0.1 s apart, and the round trip's jitter (a pose late here and there) moves a gap
# across that line (two of the simulation's lie 0.103 s apart; the node once saw them 0.09 s apart).
SAME_EPISODE_GAP_S = 0.15


def episodes(rows, force_cols, t_col="time_s", gap=SAME_EPISODE_GAP_S):
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


def merged(episodes, gap=SAME_EPISODE_GAP_S):
    """A summary's contact episodes with those less than `gap` s apart joined (each peak the larger)."""
    out = []
    for e in episodes:
        if out and e["t_start"] - out[-1]["t_end"] < gap:
            peaks = {k: max(v, e[k]) for k, v in out[-1].items() if k.startswith("peak_") and k in e}
            out[-1] = dict(out[-1], t_end=e["t_end"], **peaks)
        else:
            out.append(dict(e))
    return out


def start_node(*args):
    """`gshaptics node` with `args`, once it says it is ready."""
    node = subprocess.Popen([EXE, "node", *args, "--quiet", "--no-plot"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    line = ""
    while "ready" not in line:
        line = node.stdout.readline()
        if line == "":
            raise AssertionError("gshaptics node ended before it was ready: " + node.stderr.read())
    return node


class TwoProcesses(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp()
        domain = str(100 + os.getpid() % 100)
        # Reliable keep-last streams lose nothing while the reader falls no more than --depth
        # samples behind: 1000 (its most) is a second at 1 kHz, what a busy machine may stall a
        # process for (at 64, a CI run under load lost 29 of 19,214 poses).
        common = ["--ros2", "--domain", domain, "--reliable", "--depth", "1000"]
        cls.node = start_node(*common, "--out", os.path.join(cls.dir, "node"))
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
        sim_eps = merged(load_json(os.path.join(self.dir, "sim", "summary.json"))["episodes"])
        self.assertEqual(len(dev_eps), len(sim_eps), f"{dev_eps} vs {sim_eps}")
        for (t0, t1, peak), s in zip(dev_eps, sim_eps):
            # Contact starts within a few ticks (the round trip adds about one period).
            self.assertAlmostEqual(t0, s["t_start"], delta=0.02)
            self.assertAlmostEqual(peak, s["peak_force"], delta=0.1 * s["peak_force"] + 0.2)

    def test_node_saw_the_contacts(self):
        node = load_json(os.path.join(self.dir, "node", "run_summary.json"))
        sim = load_json(os.path.join(self.dir, "sim", "summary.json"))
        node_eps, sim_eps = merged(node["episodes"]), merged(sim["episodes"])
        peaks = [e["peak_contacts"] for e in node_eps]
        self.assertEqual(len(peaks), len(sim_eps), f"{node['episodes']} vs {sim['episodes']}")
        for p, s in zip(peaks, sim_eps):
            # The seen solid's touched Gaussians are the layers composited down to the hit; the
            # round trip's period of delay moves the pose a little, and a peak's count with it
            # (20 against 12 once on a busy machine, with the forces within 10 %).
            self.assertGreaterEqual(p, 1)
            self.assertAlmostEqual(p, s["peak_contacts"], delta=0.5 * s["peak_contacts"] + 5)
        self.assertGreater(node["ros2"]["markers_published"], 10)



class AdmittanceTwoProcesses(unittest.TestCase):
    """Issue 73: the paper's own kind of device over ROS 2. device-sim is a robot under a position
    servo with a force sensor at its handle; the node reads the sensor and writes the robot's
    setpoint (the virtual tool) at the servo rate. The node's run ends first: the robot must be
    left at rest while the hand still pulls on it."""

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp()
        domain = str(200 + os.getpid() % 30)
        common = ["--ros2", "--domain", domain, "--reliable", "--depth", "64", "--control", "admittance"]
        cls.node = start_node(*common, "--duration", "12", "--out", os.path.join(cls.dir, "node"))
        cls.dev = subprocess.run(
            [EXE, "device-sim", *common, "--sites", "1", "--duration", "16", "--quiet",
             "--out", os.path.join(cls.dir, "dev")], capture_output=True, text=True, timeout=300)
        cls.node_out, cls.node_err = cls.node.communicate(timeout=60)
        with open(os.path.join(cls.dir, "dev", "device_log.csv")) as f:
            cls.rows = list(csv.DictReader(f))

    def test_processes_exit_cleanly(self):
        self.assertEqual(self.dev.returncode, 0, self.dev.stderr)
        self.assertEqual(self.node.returncode, 0, self.node_err)

    def test_setpoints_flow_and_the_sensor_is_read(self):
        dev = load_json(os.path.join(self.dir, "dev", "device_summary.json"))
        node = load_json(os.path.join(self.dir, "node", "run_summary.json"))
        self.assertEqual(dev["control"], "admittance")
        self.assertEqual(node["control"]["mode"], "admittance")
        self.assertGreater(dev["setpoints_received"], 5000)
        sensor = max(sum(float(r[c]) ** 2 for c in ("user_fx", "user_fy", "user_fz")) ** 0.5 for r in self.rows)
        self.assertGreater(sensor, 2.0)

    def test_the_robot_touches_the_truck_and_gives_no_energy_back(self):
        node = load_json(os.path.join(self.dir, "node", "run_summary.json"))
        self.assertGreaterEqual(len(node["episodes"]), 1)
        self.assertGreater(max(e["peak_force"] for e in node["episodes"]), 2.0)
        for e in node["episodes"]:
            self.assertGreaterEqual(e["energy_j"], -1e-6, e)
        self.assertEqual(node["runtime"]["sensor_saturated_ticks"], 0)

    def test_the_robot_is_left_at_rest_when_the_node_stops(self):
        # The node stops at least 2 s before device-sim; over device-sim's last 2 s the hand still
        # follows its path, yet the robot holds the last setpoint (within the hand's pull over the
        # position servo's stiffness: 60 N / 200 kN/m = 0.3 mm).
        t_end = float(self.rows[-1]["time_s"])
        last = [r for r in self.rows if float(r["time_s"]) > t_end - 2.0]
        self.assertGreater(len(last), 1000)
        for axis in ("x", "y", "z"):
            values = [float(r[axis]) for r in last]
            self.assertLess(max(values) - min(values), 1e-3, axis)
        speed = max(sum(float(r[c]) ** 2 for c in ("vx", "vy", "vz")) ** 0.5 for r in last[len(last) // 2:])
        self.assertLess(speed, 0.01)
        # The node's last setpoint has zero velocity (a velocity-controlled robot would drift otherwise).
        dev = load_json(os.path.join(self.dir, "dev", "device_summary.json"))
        self.assertEqual(dev["last_setpoint"]["velocity"], [0.0, 0.0, 0.0])

if __name__ == "__main__":
    EXE = sys.argv[1]
    unittest.main(argv=[sys.argv[0], "-v"])
