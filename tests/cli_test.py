#!/usr/bin/python3
"""End-to-end tests of the gshaptics command line: the query JSON contract, pose files,
error messages and exit codes, info, the simulated probe run with its outputs, and the
real-time runtime (`run`: sim and replay devices, faults, SIGINT).

Usage: cli_test.py PATH/TO/gshaptics SCENES_DIR
"""
import csv
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import unittest

EXE = None
SCENES = None


def scene_file(name):
    """Path of a real scene; the test is skipped, saying where to put the scenes, without it."""
    path = os.path.join(SCENES, name)
    if not os.path.exists(path):
        raise unittest.SkipTest(f"real scene {path} not found: put the scenes there (or pass their folder)")
    return path


def scored(rows):
    """seen-felt's scored rays: those not in a slot narrower than the tool (the CSV's `slot`), which
    are played besides them and count for through and no force only."""
    return [r for r in rows if r["slot"] == "0"]


def load_json(path):
    with open(path) as f:
        return json.load(f)


def run(*args, check=True):
    p = subprocess.run([EXE, *args], capture_output=True, text=True, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"{args} exited {p.returncode}: {p.stderr}")
    return p


class Query(unittest.TestCase):
    def test_contract_keys_sorting_and_values(self):
        p = run("query", scene_file("donut.ply"), "--tool-center", "0.0,0.05,0.04",
                "--tool-axes", "0.03,0.02,0.02", "--tool-rotation", "0.9,0.1,0.2,0.3")
        lines = p.stdout.strip().splitlines()
        self.assertEqual(len(lines), 1)
        j = json.loads(lines[0])
        self.assertEqual(set(j), {"candidates", "prefiltered", "contacts", "query_us"})
        self.assertGreater(len(j["contacts"]), 0)
        self.assertGreaterEqual(j["candidates"], j["prefiltered"])
        self.assertGreaterEqual(j["prefiltered"], len(j["contacts"]))
        idx = [c["index"] for c in j["contacts"]]
        self.assertEqual(idx, sorted(idx))
        for c in j["contacts"]:
            self.assertEqual(set(c), {"index", "k_min", "opacity", "center"})
            self.assertTrue(0 < c["k_min"] <= 1)
            self.assertTrue(0.2 < c["opacity"] <= 1)
            self.assertEqual(len(c["center"]), 3)
        self.assertGreaterEqual(j["query_us"], 0)

    def test_pose_file_gives_json_lines_equal_to_single_queries(self):
        poses = ["# cx cy cz ax ay az qw qx qy qz", "0 0.05 0.04 0.03 0.02 0.02 1 0 0 0",
                 "", "0.05 -0.05 0.03  0.02 0.02 0.02  0.7 0 0.7 0  # trailing comment",
                 "5 5 5 0.01 0.01 0.01 1 0 0 0"]
        with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
            f.write("\n".join(poses) + "\n")
        p = run("query", scene_file("donut.ply"), "--poses", f.name)
        out = [json.loads(line) for line in p.stdout.strip().splitlines()]
        self.assertEqual(len(out), 3)
        self.assertEqual(out[2]["contacts"], [])
        single = json.loads(run("query", scene_file("donut.ply"), "--tool-center",
                                "0.05,-0.05,0.03", "--tool-axes", "0.02,0.02,0.02",
                                "--tool-rotation", "0.7,0,0.7,0").stdout)
        self.assertEqual(single["contacts"], out[1]["contacts"])

    def test_registration_moves_centres_into_the_world_frame(self):
        reg = {"scale": 2.0, "translation": [100.0, 0.0, 0.0]}
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(reg, f)
        a = json.loads(run("query", scene_file("donut.ply"), "--tool-center",
                           "0,0.05,0.04", "--tool-axes", "0.03,0.03,0.03").stdout)
        b = json.loads(run("query", scene_file("donut.ply"), "--registration", f.name,
                           "--tool-center", "100,0.1,0.08", "--tool-axes", "0.06,0.06,0.06").stdout)
        self.assertEqual([c["index"] for c in a["contacts"]], [c["index"] for c in b["contacts"]])
        for ca, cb in zip(a["contacts"], b["contacts"]):
            self.assertAlmostEqual(cb["center"][0], 100 + 2 * ca["center"][0], places=5)
            self.assertAlmostEqual(cb["k_min"], ca["k_min"], places=6)

    def test_pose_file_from_poses_command(self):
        scene = scene_file("burger.splat")
        p = run("poses", scene, "--count", "20", "--seed", "3")
        lines = [l for l in p.stdout.splitlines() if not l.startswith("#")]
        self.assertEqual(len(lines), 20)
        self.assertEqual(p.stdout, run("poses", scene, "--count", "20", "--seed", "3").stdout)
        with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
            f.write(p.stdout)
        out = run("query", scene, "--poses", f.name).stdout.strip().splitlines()
        self.assertEqual(len(out), 20)
        # near-surface poses: most touch something
        self.assertGreater(sum(len(json.loads(l)["contacts"]) > 0 for l in out), 10)

    def test_up_auto_puts_spz_and_ply_versions_of_a_scene_in_one_world(self):
        args = ["--up", "auto", "--tool-center", "0.0,0.1,1.5", "--tool-axes", "0.15,0.15,0.15"]
        a = json.loads(run("query", scene_file("biker.spz"), *args).stdout)
        b = json.loads(run("query", scene_file("biker.compressed.ply"), *args).stdout)
        ia, ib = {c["index"] for c in a["contacts"]}, {c["index"] for c in b["contacts"]}
        self.assertGreater(len(ia), 20)
        # the same Gaussians, up to the formats' quantisation at the tool's boundary
        self.assertGreater(len(ia & ib), 0.95 * max(len(ia), len(ib)))
        p = run("info", scene_file("biker.spz"))
        self.assertIn("RUB", p.stdout)

    def test_answers_on_the_large_aerial_scene(self):
        j = json.loads(run("query", scene_file("karangkidul_crop.ply"), "--tool-center",
                           "-31.25,0,43.33", "--tool-axes", "3,3,3").stdout)
        self.assertGreater(len(j["contacts"]), 0)


class Errors(unittest.TestCase):
    def test_missing_file(self):
        p = run("query", "/nonexistent/a.ply", "--tool-center", "0,0,0", "--tool-axes", "1,1,1",
                check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("/nonexistent/a.ply", p.stderr)

    def test_truncated_file(self):
        with open(scene_file("donut.ply"), "rb") as f:
            data = f.read()
        with tempfile.NamedTemporaryFile("wb", suffix=".ply", delete=False) as f:
            f.write(data[: len(data) // 2])
        p = run("info", f.name, check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn(f.name, p.stderr)
        self.assertIn("truncated", p.stderr)

    def test_bad_tool_arguments(self):
        scene = scene_file("donut.ply")
        p = run("query", scene, "--tool-center", "0,0", "--tool-axes", "1,1,1", check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--tool-center", p.stderr)
        p = run("query", scene, "--tool-center", "0,0,0", "--tool-axes", "1,0,1", check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("semi-axes must be > 0", p.stderr)

    def test_bad_pose_line_is_named(self):
        with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
            f.write("0 0 0 1 1 1 1 0 0 0\n0 0 0 1 1 1 1 0 0\n")
        p = run("query", scene_file("donut.ply"), "--poses", f.name, check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("line 2", p.stderr)


class Info(unittest.TestCase):
    def test_info_reports_counts_and_filter(self):
        p = run("info", scene_file("fruitdrops.ply"))
        self.assertIn("4721 in file", p.stdout)
        self.assertIn("SH degree  3", p.stdout)
        self.assertIn("transform", p.stdout)
        # a default run's world (the seen solid keeps what a viewer draws), then the 0.2 filter's
        self.assertIn("opacity > 0.0039 keeps 4700 of 4721", p.stdout)
        self.assertIn("opacity > 0.2 keeps 1207 (25.6%)", p.stdout)
        # the seen normal's least ring: the drawn Gaussians' median middle axis (2 mm on a 0.45 m scene)
        self.assertIn("middle axis median, drawn Gaussians: 0.001911", p.stdout)

    def test_help_of_every_command(self):
        top = run("--help").stdout
        commands = ["info", "query", "simulate", "run", "serve", "poses", "convert", "seen-felt"]
        commands += [c for c in ("node", "device-sim") if c in top]  # with the ROS bridges
        for cmd in commands:
            p = run(cmd, "--help")
            self.assertIn("--help", p.stdout)


class SeenFelt(unittest.TestCase):
    """The real-scene benchmark in a small form: two scenes, the 1 % tool, 3 rays each way."""

    def rays(self, out_dir, *extra):
        report = os.path.join(out_dir, "SF.md")
        run("seen-felt", scene_file("truck.splat"), scene_file("burger.splat"), "--quick", "--no-plot",
            "--out", report, *extra)
        with open(os.path.join(out_dir, "sf", "seen_felt_rays.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
        with open(report) as f:
            return rows, f.read()

    def disc_rays(self, scene, percent):
        """The rays of a disc pressed vertically onto `scene` at `percent` of its size, 10 rays."""
        out = tempfile.mkdtemp()
        run("seen-felt", scene_file(scene), "--direction", "vertical", "--tool-percent", percent,
            "--tool-shape", "disc", "--rays", "10", "--surface", "seen", "--no-plot", "--out", os.path.join(out, "SF.md"))
        with open(os.path.join(out, "sf", "seen_felt_rays.csv"), newline="") as f:
            return list(csv.DictReader(f))

    def test_the_seen_surface_holds_where_it_is_seen(self):
        out = tempfile.mkdtemp()
        every, md = self.rays(out, "--surface", "seen")
        rows = scored(every)
        self.assertEqual(len(rows), 2 * 2 * 3)  # scenes x directions x rays
        self.assertTrue(all(r["no_force"] == "0" and r["through"] == "0" for r in every), every)
        for r in rows:
            self.assertEqual(r["no_force"], "0", r)
            self.assertLess(abs(float(r["felt_minus_seen"])), 0.5, r)
            self.assertGreater(float(r["onset_minus_seen"]), -1.0, r)
            # over the sphere's shadow the force begins no earlier than on its centre line
            self.assertGreaterEqual(float(r["onset_shadow_minus_seen"]), float(r["onset_minus_seen"]) - 1e-3, r)
            self.assertGreater(float(r["onset_shadow_minus_seen"]), -0.5, r)
        self.assertIn("| truck.splat |", md)
        self.assertIn("onset over the shadow, least (R)", md)
        self.assertIn("rest over the shadow, least (R)", md)
        for r in rows:  # held on what the eye sees, read over the sphere's shadow too
            self.assertGreater(float(r["rest_shadow_minus_seen"]), -0.5, r)
        self.assertFalse(any(n.endswith(".tmp") for n in os.listdir(out)))

    def test_a_stylus_on_the_seen_surface_is_felt_where_it_is_seen(self):
        out = tempfile.mkdtemp()
        every, md = self.rays(out, "--surface", "seen", "--tool-shape", "stylus", "--tool-tilt", "30")
        rows = scored(every)
        self.assertEqual(len(rows), 2 * 2 * 3)
        self.assertLessEqual(sum(r["through"] == "1" for r in every), 1)
        for r in rows:
            self.assertEqual((r["tool"], r["tilt_deg"]), ("stylus", "30"))
            self.assertEqual(r["no_force"], "0", r)
            self.assertGreater(float(r["onset_minus_seen"]), -1.0, r)
            # a stylus's onset is read over its shadow already
            self.assertEqual(r["onset_shadow_minus_seen"], r["onset_minus_seen"], r)
        self.assertIn("styluses (stylus:24R,R", md)
        self.assertIn("--tool-shape stylus", md)

    def test_a_disc_on_the_droplets_tops_is_held_on_them(self):
        # A disc (radius 4 R) pressed down on fruitdrops' droplets at the 0.5 % tool: its rim
        # overhangs where the drops' tops fall away. The edge snap once moved its contact onto a
        # tangent point a smallest semi-axis below the edge's fit, and the ray at x = 0.6521,
        # z = -2.1234 slid 1.6 R through (0.24 R held). Roaming lines out to the rim hold on the
        # drops under it; one other ray of these ten still goes 2 R through (bench/RESULTS.md).
        every = self.disc_rays("fruitdrops.ply", "0.5")
        rows = scored(every)
        self.assertEqual(len(rows), 10)
        snapped = [r for r in rows if abs(float(r["ox"]) - 0.6521) < 1e-3 and abs(float(r["oz"]) + 2.1234) < 1e-3]
        self.assertEqual(len(snapped), 1, rows)
        self.assertLess(float(snapped[0]["felt_minus_seen"]), 0.5, snapped)
        self.assertLessEqual(sum(r["through"] == "1" for r in every), 1, every)
        self.assertTrue(all(r["no_force"] == "0" for r in every), every)

    def test_a_disc_rim_on_a_thin_feature_is_a_touch_the_onset_sees(self):
        # A disc (4 R by 3.5 R across the ray) pressed down on the guitar at the 1 % tool: its
        # roaming footprint lines meet features under its rim thinner than 0.7 R. Read by 96 lines
        # over its shadow the onset put two of these ten forces 1.2 and 5.2 R before anything seen;
        # lines a twentieth of its half-thickness apart see what it touched (bench/RESULTS.md).
        rows = scored(self.disc_rays("guitar.compressed.ply", "1"))
        self.assertEqual(len(rows), 10)
        for r in rows:
            self.assertGreater(float(r["onset_shadow_minus_seen"]), -0.5, r)
            self.assertEqual(r["no_force"], "0", r)

    def test_a_stylus_tip_beside_a_raised_edge_is_held_before_it(self):
        # A stylus pressed down on the Truck at the 1 % tool: on one of these 20 rays its tip comes
        # down beside a raised edge that lies under a tenth of the tip's shadow. Its roaming lines,
        # reading one middle semi-axis ahead, met the edge only 8 R in, and the tip ended 7.9 R
        # past what the eye sees there; reading four ahead they meet it first (bench/RESULTS.md).
        out = tempfile.mkdtemp()
        run("seen-felt", scene_file("truck.splat"), "--direction", "vertical", "--tool-percent", "1",
            "--tool-shape", "stylus", "--surface", "seen", "--no-plot", "--out", os.path.join(out, "SF.md"))
        with open(os.path.join(out, "sf", "seen_felt_rays.csv"), newline="") as f:
            every = list(csv.DictReader(f))
        rows = scored(every)
        self.assertEqual(len(rows), 20)
        for r in every:
            self.assertEqual(r["through"], "0", r)
        beside = [r for r in rows if abs(float(r["ox"]) + 0.1047) < 1e-3 and abs(float(r["oz"]) - 0.2447) < 1e-3]
        self.assertEqual(len(beside), 1, rows)
        self.assertLess(float(beside[0]["onset_minus_seen"]), 1.0, beside)
        self.assertLess(float(beside[0]["felt_minus_seen"]), 0.5, beside)

    def test_a_disc_over_a_raised_patch_its_edge_search_found_is_held_there(self):
        # A disc pressed down on the halo at the 2 % tool: its first ray comes down over a raised
        # patch an inner line met, with the ring's edge search line 0.4 R under it (too little for
        # the inner line to hold by the contact band). Before the edge search's own line began a
        # contact, the disc went 1.6 R past what the eye sees before its ring met the surface, and
        # rested 0.63 R past it; with it, on the edge line 0.32 R past it (0.46 over its shadow). An
        # inner line nearer by kInnerBand (0.3 of the smallest semi-axis) holds it on the patch
        # (bench/RESULTS.md).
        out = tempfile.mkdtemp()
        run("seen-felt", scene_file("halo.ply"), "--direction", "vertical", "--tool-percent", "2",
            "--tool-shape", "disc", "--surface", "seen", "--rays", "1", "--no-plot", "--out", os.path.join(out, "SF.md"))
        with open(os.path.join(out, "sf", "seen_felt_rays.csv"), newline="") as f:
            rows = scored(list(csv.DictReader(f)))
        self.assertEqual(len(rows), 1)
        self.assertAlmostEqual(float(rows[0]["ox"]), 1.31064, places=4)
        self.assertLess(float(rows[0]["onset_shadow_minus_seen"]), 1.0, rows)
        self.assertLess(float(rows[0]["felt_minus_seen"]), 0.15, rows)
        self.assertLess(float(rows[0]["rest_shadow_minus_seen"]), 0.3, rows)

    def test_rays_aim_at_the_objects_and_the_seen_truth_is_the_captured_file(self):
        out = tempfile.mkdtemp()
        report = os.path.join(out, "SF.md")
        box = (0.0, 0.0, -1.0, 1.0, 1.0, 1.0)  # a chunk of the truck, heavy enough to stay put
        run("seen-felt", scene_file("truck.splat"), "--quick", "--no-plot", "--out", report,
            "--object", "box:" + ",".join(str(v) for v in box) + ":mass=1000:friction=1", "--direction", "vertical")
        with open(os.path.join(out, "sf", "seen_felt_rays.csv"), newline="") as f:
            rows = scored(list(csv.DictReader(f)))
        self.assertEqual(len(rows), 3)
        for r in rows:
            seen = [float(r["o" + a]) + float(r["seen"]) * float(r["u" + a]) for a in "xyz"]
            # The seen point lies on the object's Gaussians (within a tool radius of its box) ...
            for k in range(3):
                self.assertGreater(seen[k], box[k] - float(r["tool_radius"]), r)
                self.assertLess(seen[k], box[k + 3] + float(r["tool_radius"]), r)
            # ... and the hand meets it there.
            self.assertEqual(r["no_force"], "0", r)
        bad = run("seen-felt", scene_file("truck.splat"), scene_file("burger.splat"), "--quick", "--no-plot",
                  "--out", report, "--object", "box:0,0,-1,1,1,1", check=False)
        self.assertNotEqual(bad.returncode, 0)
        self.assertIn("exactly one scene", bad.stderr)

    def test_the_paper_model_is_felt_at_the_device(self):
        every, _ = self.rays(tempfile.mkdtemp(), "--force-model", "paper", "--direction", "vertical")
        rows = scored(every)
        self.assertEqual(len(rows), 2 * 3)
        for r in rows:
            self.assertAlmostEqual(float(r["felt_minus_seen"]), 4.0, delta=0.1)
            self.assertEqual(r["through"], "1")

    def test_bad_input_is_refused(self):
        p = run("seen-felt", "--quick", "--out", os.path.join(tempfile.mkdtemp(), "x.txt"), scene_file("truck.splat"),
                check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("expected a .md file", p.stderr)
        p = run("seen-felt", "--quick", "--direction", "sideways", scene_file("truck.splat"), check=False)
        self.assertNotEqual(p.returncode, 0)
        p = run("seen-felt", "--quick", "--tool-shape", "cone", scene_file("truck.splat"), check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--tool-shape", p.stderr)


def fidelity_cells_on_and_off(option, row_start, pick, *args):
    """Runs `fidelity` with `option` on and off (and `args`); returns {value: pick(cells)} for the
    first report row starting with `row_start` (its cells split on "|")."""
    cells = {}
    work = tempfile.mkdtemp()
    for value in ("on", "off"):
        out = os.path.join(work, value + ".md")
        run("fidelity", *args, "--no-plot", "--scene-dir", os.path.join(work, "scenes"), "--out", out, option, value)
        with open(out) as f:
            row = next(line for line in f if line.startswith(row_start))
        cells[value] = pick(row.split("|"))
    return cells


class Simulate(unittest.TestCase):
    def assert_on_off_option(self, option):
        """`option` is in fidelity's help, and a value other than on or off is refused by name."""
        self.assertIn(option, run("fidelity", "--help").stdout)
        bad = run("fidelity", "--quick", "--no-plot", option, "maybe", check=False)
        self.assertNotEqual(bad.returncode, 0)
        self.assertIn(option, bad.stderr)

    def test_probe_run_on_bundled_truck(self):
        out = tempfile.mkdtemp()
        p = run("simulate", "--out", out, "--quiet")
        summary = load_json(os.path.join(out, "summary.json"))
        self.assertEqual(len(summary["sites"]), 7)
        self.assertGreaterEqual(len(summary["episodes"]), 7)
        for ep in summary["episodes"]:
            self.assertGreater(ep["peak_contacts"], 0)
        self.assertGreater(sum(ep["peak_force"] > 0.5 for ep in summary["episodes"]), 6)
        with open(os.path.join(out, "probe_log.csv")) as f:
            header = f.readline().strip().split(",")
            rows = f.readlines()
        self.assertEqual(header[:4], ["time_s", "x", "y", "z"])
        self.assertIn("query_us", header)
        self.assertEqual(len(rows), summary["ticks"])
        with open(os.path.join(out, "probe_run.png"), "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertIn("query time p50", p.stdout)
        self.assertFalse(any(n.endswith(".tmp") for n in os.listdir(out)))

    def test_the_demo_gives_no_energy_back_under_either_control(self):
        """Issue 73: `simulate` on the bundled Truck (the demo) with passivity on: no contact
        episode gives energy back, with the ideal device (impedance) or the simulated robot
        (admittance, whose log adds the virtual tool and whose sensor reads the hand)."""
        for control in ("impedance", "admittance"):
            out = tempfile.mkdtemp()
            p = run("simulate", "--control", control, "--out", out, "--quiet", "--no-plot")
            summary = load_json(os.path.join(out, "summary.json"))
            self.assertEqual(summary["control"]["mode"], control)
            self.assertGreaterEqual(len(summary["episodes"]), 7, control)
            worst = min(ep["energy_j"] for ep in summary["episodes"])
            self.assertGreaterEqual(worst, -1e-6, control)  # kEnergyTolerance
            self.assertNotIn("gave energy back", p.stdout)
            self.assertEqual(summary["sites_touched"], 7, control)
            with open(os.path.join(out, "probe_log.csv")) as f:
                header = f.readline().strip().split(",")
            self.assertEqual("setpoint_x" in header, control == "admittance")
            if control == "admittance":
                self.assertEqual(summary["control"]["virtual_mass_kg"], 3.0)
                self.assertIn("position servo with a force sensor", p.stdout)

    def test_control_must_match_the_device(self):
        """An impedance-type device refuses admittance control, naming the device."""
        sim_out = tempfile.mkdtemp()
        run("simulate", "--sites", "1", "--out", sim_out, "--quiet", "--no-plot")
        p = run("run", "--device", "replay:" + os.path.join(sim_out, "probe_log.csv"), "--simulated-time",
                "--control", "admittance", "--quiet", "--no-plot", "--out", tempfile.mkdtemp(), check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("admittance control needs an admittance-type device", p.stderr)
        self.assertIn("impedance-type", p.stderr)
        p = run("simulate", "--control", "both", check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--control", p.stderr)

    def test_simulate_and_a_replay_of_its_log_command_the_same_force(self):
        """One servo step: `simulate` and `run --device replay:LOG --simulated-time` give the same
        force tick by tick (within 1 % of the peak) and the same energy W, in both modes. The
        passivity controller's cap is given: by default it is the device's own, and a replay does
        not know the simulated device's."""
        for mode in (["--inline", "--passivity-max-damping", "1500"],
                     ["--decoupled", "--latency", "2", "--passivity-max-damping", "1500"]):
            sim_out, rep_out = tempfile.mkdtemp(), tempfile.mkdtemp()
            run("simulate", "--sites", "2", "--out", sim_out, "--quiet", "--no-plot", *mode)
            summary = load_json(os.path.join(sim_out, "summary.json"))
            run("run", "--device", "replay:" + os.path.join(sim_out, "probe_log.csv"), "--simulated-time",
                "--tool-radius", repr(summary["tool_radius"]), "--quiet", "--no-plot", "--out", rep_out, *mode)
            a = read_log(os.path.join(sim_out, "probe_log.csv"))
            b = read_log(os.path.join(rep_out, "servo_log.csv"))
            force = lambda r: (float(r["fx"]), float(r["fy"]), float(r["fz"]))
            peak = max(math.hypot(*force(r)) for r in a)
            self.assertGreater(peak, 1.0, mode)
            n = min(len(a), len(b)) - 1
            self.assertGreater(n, 0.99 * len(a))
            worst = max(math.dist(force(a[i]), force(b[i])) for i in range(n))
            self.assertLessEqual(worst, 0.01 * peak, mode)

            def energy(rows):
                w = 0.0
                for i in range(n - 1):
                    f0, f1 = force(rows[i]), force(rows[i + 1])
                    dx = [float(rows[i + 1][k]) - float(rows[i][k]) for k in "xyz"]
                    w -= 0.5 * sum((f0[j] + f1[j]) * dx[j] for j in range(3))
                return w
            self.assertAlmostEqual(energy(a), energy(b), delta=0.01 * abs(energy(a)) + 1e-6)
            rs = load_json(os.path.join(rep_out, "run_summary.json"))
            self.assertTrue(rs["simulated_time"])
            self.assertEqual(summary["mode"], "inline" if mode[0] == "--inline" else "decoupled, 2 ticks latency")


    def test_run_keeps_the_faint_gaussians_for_the_seen_solid(self):
        """`run --surface seen` loads the world as `simulate --surface seen` does, with every
        Gaussian a viewer draws (--min-opacity left to the model: 1/255), and 0.2 on the ellipsoids
        (run once filtered at 0.2 whatever the surface)."""
        sim_out = tempfile.mkdtemp()
        run("simulate", "--sites", "1", "--out", sim_out, "--quiet", "--no-plot")
        radius = repr(load_json(os.path.join(sim_out, "summary.json"))["tool_radius"])
        for surface, kept in (("seen", "opacity > 0.0039: kept 116544 (100.0%)"), ("ellipsoids", "opacity > 0.2")):
            p = run("run", "--device", "replay:" + os.path.join(sim_out, "probe_log.csv"), "--simulated-time",
                    "--tool-radius", radius, "--quiet", "--no-plot", "--out", tempfile.mkdtemp(), "--surface", surface)
            self.assertIn(kept, p.stdout, surface)

    def test_energy_bound_is_an_option_of_the_proxy(self):
        self.assertIn("--energy-bound", run("simulate", "--help").stdout)
        for value in ("on", "off"):
            out = tempfile.mkdtemp()
            run("simulate", "--sites", "1", "--out", out, "--quiet", "--no-plot", "--surface", "ellipsoids", "--energy-bound", value)
            self.assertEqual(load_json(os.path.join(out, "summary.json"))["renderer"], "proxy")
        bad = run("simulate", "--sites", "1", "--quiet", "--no-plot", "--energy-bound", "sometimes", check=False)
        self.assertNotEqual(bad.returncode, 0)
        self.assertIn("--energy-bound", bad.stderr)


    def test_device_shading_is_an_option_of_the_proxy(self):
        self.assertIn("--device-shading", run("simulate", "--help").stdout)
        out = tempfile.mkdtemp()
        run("simulate", "--sites", "1", "--out", out, "--quiet", "--no-plot", "--surface", "ellipsoids", "--device-shading", "0")
        self.assertEqual(load_json(os.path.join(out, "summary.json"))["renderer"], "proxy")
        bad = run("simulate", "--sites", "1", "--quiet", "--no-plot", "--device-shading", "-1", check=False)
        self.assertNotEqual(bad.returncode, 0)
        self.assertIn("--device-shading", bad.stderr)

    def test_an_option_that_does_not_apply_is_refused_before_the_scene_loads(self):
        cases = [(("--surface", "ellipsoids", "--tool", "stylus:0.06,0.005", "--corner-normal", "off"), "--corner-normal serves a one-part tool"),
                 (("--surface", "ellipsoids", "--tool", "stylus:0.06,0.005", "--device-shading", "0"), "--device-shading serves a one-part tool"),
                 (("--surface", "ellipsoids", "--near-lists", "off",), "--near-lists serves a tool with a shape"),
                 (("--force-model", "paper", "--stiffness", "500"), "--stiffness applies to the proxy model only"),
                 (("--k-base", "3"), "--k-base applies to the paper model only"),
                 (("--surface", "seen", "--crest-hold", "off"),
                  "--crest-hold serves --surface ellipsoids only (--surface is seen)"),
                 (("--surface", "ellipsoids", "--seen-window", "64"), "--seen-window serves --surface seen only")]
        for args, message in cases:
            p = run("simulate", "--sites", "1", "--quiet", "--no-plot", *args, check=False)
            self.assertEqual(p.returncode, 2, (args, p.stderr))
            self.assertIn(message, p.stderr, args)
            self.assertNotIn("scene ", p.stdout, args)  # refused before the world was built
        # The same options where they apply still run.
        out = tempfile.mkdtemp()
        run("simulate", "--sites", "1", "--out", out, "--quiet", "--no-plot", "--tool", "stylus:0.06,0.005",
            "--surface", "ellipsoids", "--near-lists", "off", "--opacity-stiffness")
        self.assertEqual(load_json(os.path.join(out, "summary.json"))["tool"]["spec"], "stylus:0.06,0.005")

    def test_synth_edge_sigmas_apply_to_shapes_with_convex_edges_only(self):
        d = tempfile.mkdtemp()
        cube = os.path.join(d, "cube.ply")
        run("synth", "cube", cube, "--spacing", "0.008", "--edge-sigmas", "1.17")
        with open(cube, "rb") as f:
            self.assertIn(b"comment edge_sigmas 1.17", f.read(4000))
        for shape in ("sphere", "grating"):
            path = os.path.join(d, shape + ".ply")
            p = run("synth", shape, path, "--edge-sigmas", "1", check=False)
            self.assertNotEqual(p.returncode, 0, shape)
            self.assertIn("--edge-sigmas applies to the shapes with convex edges", p.stderr, shape)
            self.assertFalse(os.path.exists(path), shape)
        p = run("fidelity", "--quick", "--shape", "plane", "--edge-sigmas", "1", "--no-plot",
                "--out", os.path.join(d, "F.md"), check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--edge-sigmas needs a shape with convex edges", p.stderr)

    def test_materials_from_synth_run_and_bad_maps_are_named(self):
        d = tempfile.mkdtemp()
        plane, mp = os.path.join(d, "plane.ply"), os.path.join(d, "two.json")
        out = run("synth", "plane", plane, "--two-materials", mp).stdout
        self.assertIn("materials  " + mp, out)
        self.assertEqual([m["name"] for m in load_json(mp)["materials"]], ["soft", "hard"])
        grating = os.path.join(d, "grating.ply")
        self.assertIn("grating of wavelength 2 mm", run("synth", "grating", grating, "--grating", "2,0.1").stdout)
        run("simulate", plane, "--sites", "1", "--out", d, "--quiet", "--no-plot", "--materials", mp)
        self.assertEqual(load_json(os.path.join(d, "summary.json"))["renderer"], "proxy")
        bad = os.path.join(d, "bad.json")
        with open(bad, "w") as f:
            f.write('{"materials": [{"name": "a"}], "regions": [{"material": "b", "indices": [1]}]}')
        p = run("simulate", plane, "--sites", "1", "--quiet", "--no-plot", "--materials", bad, check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn(bad + ": regions[0]: no material named \"b\"", p.stderr)
        # A tool with a shape reads the map too.
        run("simulate", plane, "--sites", "1", "--out", d, "--quiet", "--no-plot", "--materials", mp, "--tool",
            "stylus:0.06,0.005")
        self.assertEqual(load_json(os.path.join(d, "summary.json"))["tool"]["spec"], "stylus:0.06,0.005")
        # Colour regions select on the scene's colours (the bundled Truck): each says how many.
        colour = os.path.join(d, "colour.json")
        with open(colour, "w") as f:
            f.write('{"materials": [{"name": "paint"}, {"name": "dark"}], "regions": ['
                    '{"material": "paint", "colour": {"rgb": [0.6, 0.3, 0.2], "clusters": 4}},'
                    '{"material": "dark", "colour": {"rgb": [0.1, 0.1, 0.1], "tolerance": 0.15}}]}')
        out = run("simulate", "--sites", "1", "--out", d, "--quiet", "--no-plot", "--materials", colour).stdout
        picked = re.findall(r"materials  regions\[(\d)\] \((\w+)\): colour .* selects (\d+) of (\d+) Gaussians", out)
        self.assertEqual([(r, m) for r, m, _, _ in picked], [("0", "paint"), ("1", "dark")], out)
        for _, _, n, total in picked:
            self.assertTrue(0 < int(n) < int(total), out)

    def test_a_reports_command_names_the_force_options_and_seed_given(self):
        # The fidelity report cites the command that reproduces it: the force options as given
        # (a flag without a value), the seed, and nothing it did not take.
        work = tempfile.mkdtemp()
        out = os.path.join(work, "q.md")
        run("fidelity", "--quick", "--no-plot", "--seed", "3", "--crest-hold", "off", "--stiffness", "800",
            "--opacity-stiffness", "--surface", "ellipsoids", "--scene-dir", os.path.join(work, "scenes"), "--out", out)
        with open(out) as f:
            command = next(line for line in f if line.startswith("Command:"))
        self.assertIn("--force-model proxy --stiffness 800 --opacity-stiffness --crest-hold off", command)
        self.assertIn("--seed 3", command)
        self.assertNotIn("--out", command)
        self.assertNotIn("true", command)

    def test_corner_normal_is_an_option_of_the_proxy(self):
        self.assert_on_off_option("--corner-normal")

    def test_crest_hold_is_an_option_of_the_proxy_and_evens_the_cube_corners_stiffness(self):
        # Seed 1's cube, 5 mm tool: the corners' stiffness across the three densities (the
        # fidelity table "Stiffness across densities"), with the proxy held on the crest and not.
        self.assert_on_off_option("--crest-hold")
        ratio = fidelity_cells_on_and_off("--crest-hold", "| cube | corner | 5 | 2 mm:", lambda c: float(c[5]),
                                          "--seed", "1", "--shape", "cube", "--wrench-sites", "0", "--defect", "none",
                                          "--surface", "ellipsoids")
        self.assertLessEqual(ratio["on"], 1.05, ratio)
        self.assertGreater(ratio["off"], 1.05, ratio)

    def test_face_average_is_an_option_of_the_proxy(self):
        self.assert_on_off_option("--face-average")

    def test_overhang_falloff_is_an_option_of_the_proxy_and_changes_the_cube_edge(self):
        # Seed 25's 8 mm cube: a disc overhanging an edge turns the 5 mm tool's force at one edge
        # site (ProxyRenderer.AnOverhangingDiscOfTheOtherFaceDoesNotTurnTheFaceItBlocks). The
        # crest hold keeps that tool off the fin: off, so that the falloff is what is measured.
        self.assert_on_off_option("--overhang-falloff")
        p95 = fidelity_cells_on_and_off("--overhang-falloff", "| cube | edge | 8 | 5 |",
                                        lambda c: float(c[10].split("/")[1]), "--seed", "25", "--shape", "cube",
                                        "--spacing", "8", "--wrench-sites", "0", "--crest-hold", "off",
                                        "--surface", "ellipsoids")
        self.assertLessEqual(p95["on"], 5.0, p95)
        self.assertGreater(p95["off"], 10.0, p95)


class Objects(unittest.TestCase):
    def test_the_hand_pushes_the_box_and_feels_its_friction(self):
        """`simulate --scenario push`: the box slides, the friction felt while it slides is mu m g
        within 5 %, the tool never enters the box, and a heavier box with more friction is felt as
        such; a negative friction is refused."""
        for mass, mu in ((None, None), ("0.8", "0.5")):
            out = tempfile.mkdtemp()
            extra = ["--object-mass", mass, "--object-friction", mu] if mass else []
            run("simulate", "--scenario", "push", "--out", out, "--quiet", "--no-plot", *extra)
            s = load_json(os.path.join(out, "summary.json"))
            if mass:
                self.assertEqual(s["box"]["mass_kg"], float(mass))
                self.assertEqual(s["box"]["friction"], float(mu))
            self.assertAlmostEqual(s["friction_expected_N"], s["box"]["mass_kg"] * s["box"]["friction"] * 9.81, places=6)
            self.assertGreater(s["travelled_m"], 0.05)
            self.assertGreater(s["sliding_ticks"], 200)
            self.assertAlmostEqual(s["friction_felt_over_expected"], 1.0, delta=0.05)
            self.assertLess(s["deepest_box_depth_m"], 1e-3)  # (0.1 tool radii; either surface)
            with open(os.path.join(out, "push_log.csv")) as f:
                rows = list(csv.DictReader(f))
            self.assertEqual(len(rows), s["ticks"])
        bad = run("simulate", "--scenario", "push", "--object-friction", "-1", check=False)
        self.assertNotEqual(bad.returncode, 0)
        self.assertIn("--object-friction", bad.stderr)

    def test_an_object_cut_from_the_truck_leaves_the_static_world(self):
        """`simulate --object`: the Gaussians in the box leave the static world and become an object
        with its dynamics; a box that holds no Gaussian, or a malformed one, is refused."""
        plain = run("simulate", "--sites", "1", "--out", tempfile.mkdtemp(), "--quiet", "--no-plot").stdout
        cut_out = tempfile.mkdtemp()
        cut_run = run("simulate", "--sites", "1", "--out", cut_out, "--quiet", "--no-plot",
                      "--object", "box:0,0,-1,1,1,1:mass=2:friction=0.6")
        cut = cut_run.stdout
        # A chunk of the truck's body, its hull's lowest tips under the ground fitted around it, is
        # seated on that ground (it fell 1.3 m by itself before), and stands.
        self.assertRegex(cut, r"object +0: seated on the ground: as cut its hull's lowest point stood [0-9.]+ m under it")
        self.assertNotIn("warning", cut_run.stderr)
        self.assertRegex(cut, r"object +0: \d+ Gaussians kept, 2 kg, mu 0\.6, 1 convex piece,")
        kept = lambda text: int(re.search(r"^world +(\d+) Gaussians", text, re.M).group(1))
        moved = int(re.search(r"^object +0: (\d+) Gaussians cut", cut, re.M).group(1))
        self.assertGreater(moved, 1000)
        self.assertLess(kept(cut), kept(plain))
        self.assertGreater(kept(cut), kept(plain) - moved - 1)
        self.assertRegex(cut, r"object +0: \d+ Gaussians kept, 2 kg, mu 0\.6")
        self.assertRegex(cut, r"support +(a plane fitted to \d+ Gaussians|no ground around the objects)")
        objects = load_json(os.path.join(cut_out, "summary.json"))["objects"]
        self.assertEqual(len(objects), 1)
        drift = {k: objects[0].pop(k) for k in ("untouched_moved_m", "untouched_turned_rad")}
        self.assertEqual(objects, [{"spec": "box:0,0,-1,1,1,1:mass=2:friction=0.6", "mass_kg": 2.0,
                                    "friction": 0.6, "gaussians_cut": moved}])
        self.assertLess(drift["untouched_moved_m"], 0.01)
        # A file object is placed by its own registration, never seated: the ground-truth cube at
        # the origin does not stand on the Truck's ground, moves by itself, and says so.
        cube = os.path.join(tempfile.mkdtemp(), "cube.ply")
        run("synth", "cube", cube, "--spacing", "0.01")
        file_run = run("simulate", "--sites", "1", "--out", tempfile.mkdtemp(), "--quiet", "--no-plot",
                       "--object", "file:" + cube + ":mass=1")
        self.assertNotIn("seated", file_run.stdout)
        self.assertRegex(file_run.stderr, r"warning: object 0 \(file:.*cube\.ply:mass=1\) moves "
                                          r"[0-9.]+ m and turns \d+ deg in its first second untouched")
        for spec, message in (("box:9,9,9,10,10,10", "no Gaussian with opacity above"),
                              ("box:1,2", "a box takes six numbers"),
                              ("box:0,0,-1,1,1,1:hulls=0", "hulls must be a whole number from 1 to 16")):
            bad = run("simulate", "--sites", "1", "--no-plot", "--quiet", "--out", tempfile.mkdtemp(),
                      "--object", spec, check=False)
            self.assertEqual(bad.returncode, 2, bad.stderr)
            self.assertIn(message, bad.stderr)
        # The same object from an objects JSON (--objects); a broken one names its file and entry.
        d = tempfile.mkdtemp()
        good, broken = os.path.join(d, "objects.json"), os.path.join(d, "broken.json")
        with open(good, "w") as f:
            json.dump({"objects": [{"box": [0, 0, -1, 1, 1, 1], "mass": 2, "friction": 0.6}]}, f)
        with open(broken, "w") as f:
            json.dump({"objects": [{"box": [0, 0, -1, 1, 1, 1]}, {"file": ""}]}, f)
        from_json = run("simulate", "--sites", "1", "--out", tempfile.mkdtemp(), "--quiet", "--no-plot",
                        "--objects", good).stdout
        self.assertEqual(int(re.search(r"^object +0: (\d+) Gaussians cut", from_json, re.M).group(1)), moved)
        self.assertRegex(from_json, r"object +0: \d+ Gaussians kept, 2 kg, mu 0\.6")
        bad = run("simulate", "--sites", "1", "--no-plot", "--quiet", "--out", tempfile.mkdtemp(),
                  "--objects", broken, check=False)
        self.assertEqual(bad.returncode, 2, bad.stderr)
        self.assertIn("broken.json: objects[1]", bad.stderr)
        # A static support (its Gaussians stay in the world: the static world keeps its size).
        mjcf = os.path.join(tempfile.mkdtemp(), "objects.xml")
        held = run("simulate", "--sites", "1", "--out", tempfile.mkdtemp(), "--quiet", "--no-plot",
                   "--object", "box:0,0,-1,1,1,1", "--support", "box:-1,-1,-1,0,0,1", "--objects-mjcf", mjcf).stdout
        self.assertRegex(held, r"support +0: \d+ Gaussians of the scene \(box:-1,-1,-1,0,0,1\)")
        # The MuJoCo model as MJCF (--objects-mjcf): the object a free body of its hull, the support's hull.
        with open(mjcf) as f:
            model = f.read()
        self.assertIn("<mujoco model='gshaptics_objects'>", model)
        self.assertEqual(model.count("<freejoint/>"), 1)
        self.assertIn("mesh='hull0'", model)
        self.assertIn("mesh='support0'", model)
        self.assertEqual(kept(held), kept(cut))
        self.assertRegex(held, r"around the supports|no ground around the supports")
        alone = run("simulate", "--sites", "1", "--no-plot", "--quiet", "--out", tempfile.mkdtemp(),
                    "--support", "box:-1,-1,-1,0,0,1", check=False)
        self.assertEqual(alone.returncode, 2, alone.stderr)
        self.assertIn("--support: give the objects", alone.stderr)


class DataSafety(unittest.TestCase):
    """Issue 35: a failed run leaves the previous results untouched and creates no folder; every
    check comes before the scene is loaded; a FIFO is refused, not waited on."""

    def snapshot(self, d):
        out = {}
        for name in sorted(os.listdir(d)):
            with open(os.path.join(d, name), "rb") as f:
                out[name] = f.read()
        return out

    def test_a_failed_run_keeps_the_previous_results(self):
        out = tempfile.mkdtemp()
        run("simulate", "--sites", "1", "--quiet", "--no-plot", "--out", out)
        before = self.snapshot(out)
        self.assertIn("probe_log.csv", before)
        work = tempfile.mkdtemp()
        truncated = os.path.join(work, "truck.splat")
        bundled = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data", "truck.splat")
        with open(bundled, "rb") as src, open(truncated, "wb") as dst:
            dst.write(src.read(1000))
        failures = [
            ("simulate", "--reg-scale", "-1", "--out", out),
            ("simulate", "--registration", os.path.join(work, "missing.json"), "--out", out),
            ("simulate", truncated, "--out", out),
            ("run", "--device", "dhd", "--duration", "1", "--out", out),
            ("run", "--workspace-scale", "nan", "--duration", "1", "--out", out),
        ]
        for args in failures:
            p = run(*args, "--quiet", check=False)
            self.assertNotEqual(p.returncode, 0, args)
            self.assertEqual(self.snapshot(out), before, f"{args} changed the previous results")
        # A failure creates no folder either.
        fresh = os.path.join(work, "new", "folder")
        p = run("simulate", os.path.join(work, "nonexistent.ply"), "--out", fresh, "--quiet", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertFalse(os.path.exists(os.path.join(work, "new")))

    def test_device_errors_come_before_the_scene_is_loaded(self):
        # karangkidul_crop takes ~0.5 s to load: the error must come before, without a scene line.
        for args, says in ((("--device", "dhd"), "libdhd.so not found"),
                           (("--device", "replay:/nonexistent.csv"), "/nonexistent.csv"),
                           (("--workspace-scale", "nan"), "--workspace-scale")):
            p = run("run", *args, "--duration", "1", "--quiet", check=False)
            self.assertEqual(p.returncode, 2, args)
            self.assertIn(says, p.stderr)
            self.assertNotIn("gaussians", p.stdout.lower(), f"{args}: the scene was loaded first")

    def test_a_fifo_is_refused_not_waited_on(self):
        d = tempfile.mkdtemp()
        fifo = os.path.join(d, "scene.ply")
        os.mkfifo(fifo)
        p = subprocess.run([EXE, "info", fifo], capture_output=True, text=True, timeout=30)
        self.assertEqual(p.returncode, 2)
        self.assertIn("FIFO", p.stderr)
        p = subprocess.run([EXE, "simulate", "--registration", fifo, "--quiet"], capture_output=True, text=True,
                           timeout=30)
        self.assertEqual(p.returncode, 2)
        self.assertIn("FIFO", p.stderr)


def read_log(path):
    with open(path) as f:
        return list(csv.DictReader(f))


class Run(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.out = tempfile.mkdtemp()
        cls.proc = run("run", "--duration", "5", "--quiet", "--out", cls.out)
        cls.summary = load_json(os.path.join(cls.out, "run_summary.json"))
        cls.log = read_log(os.path.join(cls.out, "servo_log.csv"))

    def test_real_time_run_writes_log_summary_and_figure(self):
        rt = self.summary["runtime"]
        self.assertGreaterEqual(rt["ticks"] + rt["skipped_periods"], 5000)
        self.assertGreater(rt["ticks"], 4500)
        self.assertEqual(len(self.log), rt["ticks"])
        self.assertEqual(self.summary["mode"], "inline")  # the runtime's default (kDefaultInlineQuery)
        for key in ("jitter_us", "result_age_us", "held", "fading", "flags", "desired_fx"):
            self.assertIn(key, self.log[0])
        self.assertEqual([float(self.log[-1][k]) for k in ("fx", "fy", "fz")], [0.0, 0.0, 0.0])
        self.assertGreater(max(int(r["contacts"]) for r in self.log), 0)
        # |F| <= F_max = 30 N, to the log's 5 decimals per component.
        self.assertLessEqual(max(math.hypot(float(r["fx"]), float(r["fy"]), float(r["fz"]))
                                 for r in self.log), 30.0 + 2e-5)
        with open(os.path.join(self.out, "run.png"), "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertIn("deadline misses", self.proc.stdout)
        self.assertIn("stale", self.proc.stdout)
        self.assertFalse(any(n.endswith(".tmp") for n in os.listdir(self.out)))

    def test_replay_of_the_recorded_run_touches_the_same_places(self):
        out = tempfile.mkdtemp()
        log_path = os.path.join(self.out, "servo_log.csv")
        p = run("run", "--device", "replay:" + log_path, "--quiet", "--no-plot", "--out", out,
                "--tool-radius", str(self.summary["tool_radius"]))
        self.assertIn("replay", p.stdout)
        replay = read_log(os.path.join(out, "servo_log.csv"))
        # The replay ends with the log (plus the stop ramp), not at a fixed duration.
        self.assertAlmostEqual(float(replay[-1]["time_s"]), float(self.log[-1]["time_s"]), delta=0.3)
        orig = max(int(r["contacts"]) for r in self.log)
        again = max(int(r["contacts"]) for r in replay)
        self.assertGreater(again, 0.5 * orig)
        self.assertLess(again, 2.0 * orig + 5)

    def test_compound_tool_replay_counts_the_torque_a_force_only_device_drops(self):
        r = self.summary["tool_radius"]
        log_path = os.path.join(self.out, "servo_log.csv")
        for model in ("paper", "proxy"):
            out = tempfile.mkdtemp()
            tool = os.path.join(out, "tool.json")
            with open(tool, "w") as f:  # the recorded sphere at the TCP plus a smaller one beside it
                json.dump({"parts": [{"center": [0, 0, 0], "semi_axes": [r, r, r]},
                                     {"center": [2 * r, 0, 0], "semi_axes": [r / 2, r / 2, r / 2]}]}, f)
            p = run("run", "--device", "replay:" + log_path, "--simulated-time", "--quiet", "--no-plot",
                    "--out", out, "--tool", tool, "--force-model", model)
            self.assertIn("torque", p.stdout, model)
            self.assertIn("force only", p.stdout, model)
            s = load_json(os.path.join(out, "run_summary.json"))
            self.assertEqual(len(s["tool"]["parts"]), 2)
            rt = s["runtime"]
            self.assertGreater(rt["peak_torque_nm"], 0.0, model)
            self.assertGreater(rt["torque_dropped_ticks"], 0, model)
            self.assertEqual(rt["torque_limit_nm"], 0.5)
            self.assertGreater(rt["peak_force_n"], 0.0, model)
            rows = read_log(os.path.join(out, "servo_log.csv"))
            self.assertEqual({x["tx"] for x in rows} | {x["ty"] for x in rows}, {"0.000000"})  # nothing sent
        # A bad tool is named before the scene loads.
        q = run("run", "--device", "replay:" + log_path, "--tool", "stylus:0.01,0.03", "--quiet", check=False)
        self.assertEqual(q.returncode, 2)
        self.assertIn("longer than its diameter", q.stderr)
        self.assertNotIn("gaussians", q.stdout.lower())

    def test_replay_with_nan_rows_gates_the_force(self):
        out = tempfile.mkdtemp()
        path = os.path.join(out, "poses.csv")
        with open(path, "w") as f:
            f.write("time_s,x,y,z\n")
            for i in range(1001):
                t = i * 1e-3
                x = "nan" if 0.4 <= t < 0.6 else "0.0"
                f.write(f"{t:.3f},{x},0.0,3.0\n")
        p = run("run", "--device", "replay:" + path, "--quiet", "--no-plot", "--out", out)
        self.assertIn("NaN/Inf", p.stderr)
        rt = load_json(os.path.join(out, "run_summary.json"))["runtime"]
        self.assertGreater(rt["invalid_pose_ticks"], 150)
        self.assertLess(rt["invalid_pose_ticks"], 260)

    def test_sigint_ramps_down_and_exits_cleanly(self):
        out = tempfile.mkdtemp()
        p = subprocess.Popen([EXE, "run", "--duration", "60", "--quiet", "--no-plot", "--out", out],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Wait for the run to start (the scene loads first), then interrupt it.
        line = ""
        while "runtime" not in line:
            line = p.stdout.readline()
            self.assertNotEqual(line, "", "gshaptics run ended before starting")
        time.sleep(1.5)
        p.send_signal(signal.SIGINT)
        stdout, stderr = p.communicate(timeout=60)
        self.assertEqual(p.returncode, 0, stderr)
        self.assertIn("SIGINT received", stderr)
        summary = load_json(os.path.join(out, "run_summary.json"))
        self.assertTrue(summary["interrupted"])
        self.assertLess(summary["runtime"]["ticks"], 20000)
        log = read_log(os.path.join(out, "servo_log.csv"))
        self.assertEqual([float(log[-1][k]) for k in ("fx", "fy", "fz")], [0.0, 0.0, 0.0])

    def test_bad_device_arguments_are_named(self):
        p = run("run", "--device", "joystick", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("--device", p.stderr)
        out = tempfile.mkdtemp()
        path = os.path.join(out, "bad.csv")
        with open(path, "w") as f:
            f.write("time_s,x,y,z\n0,0,0,0\n0.001,0,abc,0\n")
        p = run("run", "--device", "replay:" + path, check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("bad.csv", p.stderr)
        self.assertIn("line 3", p.stderr)
        self.assertIn("'y'", p.stderr)


    def test_workspace_rotation_on_the_command_line(self):
        with tempfile.TemporaryDirectory() as d:
            p = run("run", "--device", "sim", "--simulated-time", "--duration", "0.2", "--no-plot", "--quiet",
                    "--out", d, "--workspace-rotation", "0.7071068,0,0,0.7071068")
        self.assertIn("turned [0.707, 0.000, 0.000, 0.707] (w,x,y,z)", p.stdout)
        bad = run("run", "--workspace-rotation", "0,0,0,0", check=False)
        self.assertEqual(bad.returncode, 2)
        self.assertIn("--workspace-rotation", bad.stderr)
        self.assertNotIn("scene ", bad.stdout)  # refused before the scene loads

    def test_short_run_says_it_ended_before_the_first_site(self):
        # It said "0 contact episodes, likely causes: up axis" when the run was just too short.
        with tempfile.TemporaryDirectory() as d:
            p = run("run", "--device", "sim", "--simulated-time", "--duration", "1", "--no-plot", "--quiet",
                    "--out", d)
        self.assertIn("0 contact episodes", p.stdout)
        self.assertRegex(p.stdout, r"ended at 1\.\d s, before the probe reached its first site \(at [\d.]+ s")
        self.assertNotIn("likely causes", p.stderr)

class WorldCache(unittest.TestCase):
    """--world-cache: the second run opens the world from the cache; a damaged cache is detected
    and rebuilt; a folder that cannot be written only costs the rebuild."""

    def sim(self, cache, out):
        return run("simulate", "--world-cache", cache, "--quiet", "--no-plot", "--out", out, "--sites", "1")

    def test_query_takes_the_cache_and_keeps_stdout_json(self):
        with tempfile.TemporaryDirectory() as d:
            args = ["query", scene_file("donut.ply"), "--tool-center", "0.0,0.05,0.04", "--tool-axes",
                    "0.03,0.02,0.02", "--world-cache", d]
            first, second = run(*args), run(*args)
            self.assertIn("world written to", first.stderr)
            self.assertIn("from the world cache", second.stderr)
            a, b = json.loads(first.stdout), json.loads(second.stdout)  # stdout is the JSON alone
            self.assertGreater(len(a["contacts"]), 0)
            self.assertEqual(a["contacts"], b["contacts"])

    def test_hit_damage_and_unwritable_folder(self):
        with tempfile.TemporaryDirectory() as d:
            cache = os.path.join(d, "cache")
            first = self.sim(cache, os.path.join(d, "a"))
            self.assertIn("cache      world written to", first.stdout)
            files = [f for f in os.listdir(cache) if f.endswith(".gshworld")]
            self.assertEqual(len(files), 1)
            self.assertTrue(files[0].startswith("truck-"))
            second = self.sim(cache, os.path.join(d, "b"))
            self.assertIn("from the world cache", second.stdout)
            a = load_json(os.path.join(d, "a", "summary.json"))
            b = load_json(os.path.join(d, "b", "summary.json"))
            self.assertEqual(a["gaussians_kept"], b["gaussians_kept"])
            self.assertEqual(a["gaussians_loaded"], b["gaussians_loaded"])
            # The same world gives the same run: every column but the measured query time.
            ra, rb = read_log(os.path.join(d, "a", "probe_log.csv")), read_log(os.path.join(d, "b", "probe_log.csv"))
            self.assertEqual(len(ra), len(rb))
            for x, y in zip(ra, rb):
                x.pop("query_us")
                y.pop("query_us")
                self.assertEqual(x, y)
            # A flipped byte in the cached records: detected, rebuilt, rewritten.
            path = os.path.join(cache, files[0])
            with open(path, "r+b") as f:
                f.seek(4096 + 80 * 100 + 3)
                byte = f.read(1)
                f.seek(4096 + 80 * 100 + 3)
                f.write(bytes([byte[0] ^ 0x10]))
            third = self.sim(cache, os.path.join(d, "c"))
            self.assertIn("payload hash mismatch; rebuilding", third.stderr)
            self.assertIn("cache      world written to", third.stdout)
            # A cache "folder" that is a file: a warning, and the run still completes.
            blocker = os.path.join(d, "blocker")
            open(blocker, "w").close()
            fourth = self.sim(blocker, os.path.join(d, "e"))
            self.assertIn("the world is rebuilt each time", fourth.stderr)


class Devices(unittest.TestCase):
    """`gshaptics devices` and the desktop devices on run: what is missing and why, without
    hardware; the DHD device end to end through a stand-in libdhd (GSHAPTICS_TEST_FAKE_DHD)."""

    def env(self, **extra):
        e = dict(os.environ)
        e.update({"GSHAPTICS_DHD_LIBRARY": "/nonexistent/libdhd.so",
                  "GSHAPTICS_HD_LIBRARY": "/nonexistent/libHD.so"})
        e.update(extra)
        return e

    def test_devices_without_hardware_says_what_is_missing(self):
        p = subprocess.run([EXE, "devices", "--haply-url", "ws://127.0.0.1:1/"], capture_output=True,
                           text=True, timeout=60, env=self.env())
        self.assertEqual(p.returncode, 0, p.stderr)
        rows = {line.split()[0]: line for line in p.stdout.splitlines()[1:] if line.strip()}
        self.assertIn(" yes ", rows["sim"])
        self.assertIn(" no ", rows["dhd[:N]"])
        self.assertIn("libdhd.so not found", rows["dhd[:N]"])
        self.assertIn("Force Dimension SDK", rows["dhd[:N]"])
        self.assertIn(" no ", rows["openhaptics[:NAME]"])
        self.assertIn("libHD.so not found", rows["openhaptics[:NAME]"])
        self.assertIn("OpenHaptics", rows["openhaptics[:NAME]"])
        if "haply[:N]" in rows:
            self.assertIn("ws://127.0.0.1:1/", rows["haply[:N]"])
            self.assertIn("Inverse Service", rows["haply[:N]"])

    def test_missing_device_library_is_an_error_before_the_run(self):
        with tempfile.TemporaryDirectory() as d:
            p = subprocess.run([EXE, "run", "--device", "dhd", "--duration", "1", "--out", d, "--quiet"],
                               capture_output=True, text=True, timeout=120, env=self.env())
            self.assertEqual(p.returncode, 2)
            self.assertIn("--device dhd: libdhd.so not found", p.stderr)
            self.assertFalse(os.path.exists(os.path.join(d, "run_summary.json")))
        p = run("run", "--device", "dhd:x", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("must be a number", p.stderr)

    def test_run_drives_a_dhd_device_through_its_library(self):
        fake = os.environ.get("GSHAPTICS_TEST_FAKE_DHD")
        if not fake:
            self.skipTest("GSHAPTICS_TEST_FAKE_DHD (the stand-in libdhd) not given")
        with tempfile.TemporaryDirectory() as d:
            p = subprocess.run([EXE, "run", "--device", "dhd:1", "--duration", "0.5", "--out", d, "--quiet",
                                "--no-plot", "--workspace-scale", "10", "--f-max", "30"],
                               capture_output=True, text=True, timeout=120,
                               env=self.env(GSHAPTICS_DHD_LIBRARY=fake))
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertIn("fake omega.3 (dhd:1): powered, connected, calibrated", p.stdout)
            s = load_json(os.path.join(d, "run_summary.json"))
            self.assertIn("fake omega.3", json.dumps(s))
            self.assertIn("fake omega.3 (dhd:1)", s["device"])
            self.assertGreater(s["runtime"]["ticks"], 100)
            # The omega.3's 12 N rating binds, not --f-max 30, and the summary says so.
            self.assertEqual(s["runtime"]["force_limit_n"], 12.0)
            self.assertEqual(s["runtime"]["force_limit_bound_by"], "device")
            self.assertLessEqual(s["runtime"]["peak_force_n"], 12.0)
            self.assertEqual(s["device_limits"]["max_force_n"], 12.0)
            self.assertIn("limit      12 N, bound by the device (rating of omega.3", p.stdout)


class Convert(unittest.TestCase):
    def test_splat_output_measures_and_says_what_it_loses(self):
        with tempfile.TemporaryDirectory() as d:
            lossy = run("convert", scene_file("donut.ply"), os.path.join(d, "donut.splat"), "--quiet")
            m = re.search(r"contacts changed for (\d+) of 200 tool poses", lossy.stderr)
            self.assertIsNotNone(m, lossy.stderr)
            self.assertIn(".splat is lossy", lossy.stderr)
            exact = run("convert", scene_file("donut.ply"), os.path.join(d, "donut.ply"), "--quiet")
            self.assertNotIn("lossy", exact.stderr)
            self.assertIn("lossy", run("convert", "--help").stdout)


class Stability(unittest.TestCase):
    def test_quick_sweep_writes_table_and_trials(self):
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "STABILITY.md")
            p = run("stability", "--quick", "--no-plot", "--out", out, "--control", "impedance",
                    "--stiffness", "1000", "--stiffness", "64000", "--delay", "0")
            md = open(out).read()
            rows = [l for l in md.splitlines() if l.startswith("| plane | impedance |")]
            self.assertEqual(len(rows), 2, md)  # passivity off and on
            cells = [[c.strip() for c in r.strip("|").split("|")] for r in rows]
            self.assertEqual([c[4] for c in cells], ["off", "on"])
            self.assertEqual(cells[0][5], "1000")  # 64 kN/m bounces without the controller
            self.assertEqual(cells[0][6], "4000")  # b / (T/2): 2 N s/m at 1 kHz
            trials = open(os.path.join(d, "stability", "stability_trials.csv")).read().splitlines()
            self.assertEqual(len(trials), 1 + 4)
            self.assertIn("largest stable", p.stdout)
            bad = run("stability", "--quick", "--out", os.path.join(d, "x.txt"), check=False)
            self.assertEqual(bad.returncode, 2)
            self.assertIn("expected a .md file", bad.stderr)
            self.assertFalse(os.path.exists(os.path.join(d, "x.txt")))

    def test_traces_set_the_two_controls_side_by_side(self):
        """Issue 73: at 20 kN/m with a 2 ms round trip and a 10 N push the impedance device bounces
        and the admittance robot comes to rest; --trace-stiffness keeps both traces."""
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "A.md")
            run("stability", "--no-plot", "--out", out, "--shape", "plane", "--rate", "1000", "--delay", "2",
                "--push", "10", "--stiffness", "20000", "--trace-stiffness", "20000", "--duration", "1.5")
            with open(os.path.join(d, "a", "stability_traces.csv")) as f:  # beside A.md, named after it
                rows = list(csv.DictReader(f))
            heights = {}
            for r in rows:
                heights.setdefault((r["control"], r["passivity"]), []).append(float(r["height_mm"]))
            self.assertEqual(len(heights), 4)
            for (control, _), z in heights.items():
                late = z[len(z) // 2:]
                swing = max(late) - min(late)
                if control == "impedance":
                    self.assertGreater(swing, 5.0)   # bouncing, millimetres
                else:
                    self.assertLess(swing, 0.1)      # at rest
            with open(out) as f:
                self.assertIn("--trace-stiffness 20000", f.read())


class Latency(unittest.TestCase):
    """`gshaptics latency`: the gap profile of a spinning thread, as text and JSON."""

    def test_json_profile_is_consistent(self):
        p = run("latency", "--seconds", "0.2", "--json")
        prof = json.loads(p.stdout)
        self.assertGreaterEqual(prof["seconds"], 0.2)
        self.assertLess(prof["seconds"], 5.0)
        self.assertEqual(prof["threshold_us"], 5)
        self.assertAlmostEqual(prof["per_second"], prof["count"] / prof["seconds"], delta=0.1 + 1e-3 * prof["per_second"])
        self.assertGreaterEqual(prof["lost_fraction"], 0.0)
        self.assertLess(prof["lost_fraction"], 1.0)
        if prof["count"] > 0:
            self.assertGreater(prof["median_us"], 5.0)
            self.assertLessEqual(prof["median_us"], prof["p99_us"])
            self.assertLessEqual(prof["p99_us"], prof["max_us"])
            self.assertGreater(prof["hit_probability_50us"], prof["hit_probability_10us"])
        else:
            self.assertEqual(prof["hit_probability_1ms"], 0.0)

    def test_text_report_and_bad_cpu(self):
        p = run("latency", "--seconds", "0.1", "--cpu", "0")
        self.assertIn("CPU 0 (normal scheduling)", p.stdout)
        bad = run("latency", "--cpu", "100000", check=False)
        self.assertEqual(bad.returncode, 2)
        self.assertIn("--cpu 100000", bad.stderr)


class Node(unittest.TestCase):
    """Argument and start-up errors of the network commands (the bridges' own tests run them)."""

    def setUp(self):
        top = run("--help").stdout
        if "node" not in top:
            self.skipTest("built without the ROS bridges")
        repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        os.environ["CYCLONEDDS_URI"] = "file://" + os.path.join(repo, "config", "cyclonedds-loopback.xml")

    def test_node_needs_a_transport(self):
        p = run("node", "--quiet", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("--ros2 or --ros1", p.stderr)

    def test_ros2_only_options_are_refused_with_ros1(self):
        for args in (["--depth", "5"], ["--domain", "3"], ["--reliable"], ["--best-effort-output"]):
            p = run("node", "--ros1", "--quiet", *args, check=False)
            self.assertEqual(p.returncode, 2, args)
            self.assertIn(f"{args[0]} is a ROS 2 (DDS) option", p.stderr)

    def test_device_sim_without_a_node_says_so(self):
        if "device-sim" not in run("--help").stdout:
            self.skipTest("built without ROS 2")
        p = run("device-sim", "--ros2", "--domain", "213", "--wait", "1", "--quiet", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("no node matched rt/gshaptics/tool_pose", p.stderr)


if __name__ == "__main__":
    EXE, SCENES = sys.argv[1], sys.argv[2]
    unittest.main(argv=[sys.argv[0], "-v"])
