"""Tests of the gshaptics Python module: arrays from the loaders, queries equal to the CLI's,
k_min against a NumPy float64 implementation written here, the force model, and errors."""
import json
import os
import subprocess
import tempfile

import numpy as np
import pytest

import gshaptics


@pytest.fixture(scope="module")
def donut(scenes_dir):
    return gshaptics.Scene.load(os.path.join(scenes_dir, "donut.ply"))


def test_scene_arrays_shapes_dtypes_and_report(donut):
    n = len(donut)
    assert n == 45624
    assert donut.means.shape == (n, 3) and donut.means.dtype == np.float32
    assert donut.scales.shape == (n, 3) and (donut.scales > 0).all()
    assert donut.rotations.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(donut.rotations, axis=1), 1.0, atol=1e-5)
    assert donut.opacities.shape == (n,) and ((donut.opacities >= 0) & (donut.opacities <= 1)).all()
    assert donut.source_index.dtype == np.uint32
    np.testing.assert_allclose(donut.means.min(axis=0), [-0.1032, -0.0976, -0.0091], atol=1e-3)
    assert donut.report["in_file"] == 45624 and donut.report["loaded"] == 45624
    assert donut.report["format"].startswith("INRIA")


def test_load_errors_are_python_exceptions_with_the_message(tmp_path):
    with pytest.raises(gshaptics.InputError, match="cannot open"):
        gshaptics.Scene.load(str(tmp_path / "missing.ply"))
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nend_header\n")
    with pytest.raises(ValueError, match="bad.ply"):
        gshaptics.Scene.load(str(bad))


def make_poses(world, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = world.bounds
    poses = np.zeros((n, 10))
    poses[:, :3] = rng.uniform(0.3, 0.7, size=(n, 3)) * (hi - lo) + lo
    poses[:, 3:6] = rng.uniform(0.01, 0.03, size=(n, 3))
    q = rng.normal(size=(n, 4))
    poses[:, 6:] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return poses


def test_query_many_equals_the_cli(donut, scenes_dir):
    cli = os.environ.get("GSHAPTICS_CLI")
    if not cli:
        pytest.skip("GSHAPTICS_CLI not set (run through ctest)")
    world = gshaptics.CollisionWorld(donut)
    poses = make_poses(world, 30, 1)
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
        for p in poses:
            f.write(" ".join(repr(float(x)) for x in p) + "\n")
    out = subprocess.run([cli, "query", os.path.join(scenes_dir, "donut.ply"), "--poses", f.name],
                         capture_output=True, text=True, check=True).stdout.strip().splitlines()
    results = world.query_many(poses)
    assert len(out) == len(results) == 30
    touched = 0
    for line, r in zip(out, results):
        j = json.loads(line)
        assert j["candidates"] == r.candidates and j["prefiltered"] == r.prefiltered
        assert [c["index"] for c in j["contacts"]] == r.index.tolist()
        np.testing.assert_allclose([c["k_min"] for c in j["contacts"]], r.k_min, rtol=0, atol=1e-12)
        touched += len(r) > 0
    assert touched > 5
    single = world.query(poses[3, :3], poses[3, 3:6], poses[3, 6:])
    assert single.index.tolist() == results[3].index.tolist()


def numpy_k_min(A, B, d):
    """K_min by brute force in float64: K on a fine grid of lambda, then golden section."""
    def K(lam):
        M = lam * A + (1 - lam) * B
        return 1 - lam * (1 - lam) * d @ np.linalg.solve(M, d)
    grid = np.linspace(0, 1, 401)
    k = np.array([K(x) for x in grid])
    i = int(np.argmin(k))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, 400)]
    g = (np.sqrt(5) - 1) / 2
    for _ in range(100):
        x1, x2 = b - g * (b - a), a + g * (b - a)
        if K(x1) < K(x2):
            b = x2
        else:
            a = x1
    return min(k.min(), K(0.5 * (a + b)))


def random_spd(rng, lo, hi):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    s = np.exp(rng.uniform(np.log(lo), np.log(hi), size=3))
    return q @ np.diag(s ** 2) @ q.T


def test_k_min_matches_numpy_float64():
    rng = np.random.default_rng(7)
    n = 200
    A = np.stack([random_spd(rng, 0.05, 2.0) for _ in range(n)])
    B = np.stack([random_spd(rng, 0.1, 1.0) for _ in range(n)])
    d = rng.normal(size=(n, 3)) * 1.5
    got = gshaptics.k_min(A, B, d)
    assert got.shape == (n,)
    want = np.array([numpy_k_min(A[i], B[i], d[i]) for i in range(n)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-7)
    assert (got > 0).any() and (got < 0).any()
    # broadcasting over extra leading dimensions and a single pair
    assert gshaptics.k_min(A.reshape(10, 20, 3, 3), B.reshape(10, 20, 3, 3), d.reshape(10, 20, 3)).shape == (10, 20)
    assert gshaptics.k_min(np.eye(3), 4 * np.eye(3), np.array([2.0, 0, 0])) == pytest.approx(1 - 4 / 9, abs=1e-12)


def test_bad_arguments_raise_clear_errors(donut):
    world = gshaptics.CollisionWorld(donut)
    with pytest.raises(ValueError, match="cov_a"):
        gshaptics.k_min(np.eye(2), np.eye(2), np.zeros(2))
    with pytest.raises(ValueError, match="d:"):
        gshaptics.k_min(np.stack([np.eye(3)] * 2), np.stack([np.eye(3)] * 2), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="NaN"):
        gshaptics.k_min(np.eye(3), np.eye(3), np.array([np.nan, 0, 0]))
    with pytest.raises(ValueError, match="positive definite"):
        gshaptics.k_min(np.diag([1.0, 1.0, -1.0]), np.eye(3), np.ones(3))
    with pytest.raises(ValueError, match="semi-axes"):
        world.query((0, 0, 0), (0.01, 0, 0.01))
    with pytest.raises(ValueError, match="center"):
        world.query((0, np.nan, 0), (0.01, 0.01, 0.01))
    with pytest.raises(ValueError, match=r"\(3,\)"):
        world.query((0, 0), (0.01, 0.01, 0.01))
    with pytest.raises(ValueError, match=r"\(M, 10\)"):
        world.query_many(np.zeros((4, 9)))
    with pytest.raises(TypeError):
        gshaptics.CollisionWorld(donut, registration=42)


def test_registration_dict_moves_the_world(donut):
    w0 = gshaptics.CollisionWorld(donut)
    w1 = gshaptics.CollisionWorld(donut, registration={"scale": 2.0, "translation": [100.0, 0.0, 0.0]})
    r0 = w0.query((0, 0.05, 0.04), (0.03, 0.03, 0.03))
    r1 = w1.query((100, 0.1, 0.08), (0.06, 0.06, 0.06))
    assert r0.index.tolist() == r1.index.tolist() and len(r0) > 0
    np.testing.assert_allclose(r1.center, 2 * r0.center + [100, 0, 0], atol=1e-6)
    np.testing.assert_allclose(r1.k_min, r0.k_min, atol=1e-6)


def test_force_model_pushes_out_and_resets(donut):
    world = gshaptics.CollisionWorld(donut)
    params = gshaptics.ForceParams()
    params.k_base = 0.1
    fm = gshaptics.ForceModel(params)
    tool = np.array([0.0, 0.06, 0.06])
    r = world.query(tool, (0.02, 0.02, 0.02))
    assert len(r) > 0
    f = fm.update(r, tool, (0, 0, 0), 1e-3)
    centroid = r.center.mean(axis=0)
    assert f.shape == (3,) and np.linalg.norm(f) > 0
    assert np.dot(f, tool - centroid) > 0  # away from the contacts
    assert fm.state["in_contact"]
    empty = world.query((5, 5, 5), (0.01, 0.01, 0.01))
    assert len(empty) == 0
    np.testing.assert_array_equal(fm.update(empty, (5, 5, 5), (0, 0, 0), 1e-3), 0)
    assert not fm.state["in_contact"]


def test_probe_run_on_bundled_truck(data_dir):
    truck = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(truck, registration=os.path.join(data_dir, "truck.registration.json"))
    run = world.run_probe(sites=3, tool_radius=0.07)
    assert run["position"].shape == (len(run["time"]), 3)
    assert len(run["site_touch_times"]) == 3
    assert run["contacts"].max() > 0
    touching = run["contacts"] > 0
    assert np.linalg.norm(run["force"][touching], axis=1).max() > 0.5
    assert np.all(np.linalg.norm(run["force"][~touching], axis=1) == 0)


def test_the_seen_proxy_holds_the_bundled_truck_roof_where_it_is_seen(data_dir):
    # surface="seen" (as --surface seen), on a world that keeps the faint Gaussians: lowered onto
    # the roof, it is held there, its proxy and normal its own (not the ellipsoid proxy's).
    scene = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(scene, min_opacity=1.0 / 255,
                                     registration=os.path.join(data_dir, "truck.registration.json"))
    proxy = gshaptics.ProxyRenderer(world, stiffness=800.0, f_max=30.0, surface="seen")
    r = 0.03
    z_touch = None
    for k in range(1100):  # lowered 1 mm per tick from 2 m, to 10 cm under where it first touches
        z = 2.0 - 0.001 * k if z_touch is None else max(2.0 - 0.001 * k, z_touch - 0.1)
        f = proxy.render((0.0, 0.0, z), (r, r, r), (0.0, 0.0, -1.0), 1e-3)
        if z_touch is None and np.linalg.norm(f) > 0:
            z_touch = z
    assert z_touch is not None and 0.9 < z_touch < 1.1  # the roof, ~1 m up
    assert proxy.proxy[2] > z_touch - 0.02  # held on the roof, 10 cm above the device
    assert f[2] > 0 and np.dot(f, proxy.normal) > 0.9 * np.linalg.norm(f)
    np.testing.assert_allclose(np.linalg.norm(f), 30.0)  # 800 N/m x 10 cm, clamped at f_max
    with pytest.raises(ValueError, match="surface"):
        gshaptics.ProxyRenderer(world, surface="splats")
    with pytest.raises(ValueError, match="isolation_gap"):
        gshaptics.ProxyRenderer(world, surface="seen", isolation_gap=1.0)


def test_the_ellipsoid_proxy_holds_the_bundled_truck_roof(data_dir):
    scene = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(scene, registration=os.path.join(data_dir, "truck.registration.json"))
    # A clamp of its own (a runtime's safety layer limits by default).
    proxy = gshaptics.ProxyRenderer(world, surface="ellipsoids", stiffness=800.0, f_max=30.0)
    r = 0.03
    z_touch = None
    for k in range(3000):  # lowered 1 mm per tick from above the roof to 1 m below it
        z = 2.0 - 0.001 * k
        f = proxy.render((0.0, 0.0, z), (r, r, r), (0.0, 0.0, -1.0), 1e-3)
        if z_touch is None and np.linalg.norm(f) > 0:
            z_touch = z
    assert z_touch is not None and 0.9 < z_touch < 1.1  # the roof, ~1 m up
    # With the device 2 m below the roof (1 m under the ground) the proxy is still on the roof
    # (it slides down the roof's slope toward the device, never through it) and pushes up.
    assert proxy.proxy[2] > z_touch - 0.15
    assert f[2] > 0 and np.dot(f, proxy.normal) > 0.99 * np.linalg.norm(f)
    np.testing.assert_allclose(np.linalg.norm(f), 30.0)  # clamped at f_max
    with pytest.raises(ValueError):
        gshaptics.ProxyRenderer(world, stiffness=-1.0)
    # Single floaters only: the roof holds the same way; a clump size past the rule's range is refused.
    single = gshaptics.ProxyRenderer(world, surface="ellipsoids", stiffness=800.0, f_max=30.0, floater_cluster=1)
    for k in range(3000):
        f1 = single.render((0.0, 0.0, 2.0 - 0.001 * k), (r, r, r), (0.0, 0.0, -1.0), 1e-3)
    assert single.proxy[2] > z_touch - 0.15 and f1[2] > 0
    for bad in (0, 5):
        with pytest.raises(ValueError):
            gshaptics.ProxyRenderer(world, surface="ellipsoids", floater_cluster=bad)
    # Device shading off: the roof holds the same way; a negative share is refused.
    plain = gshaptics.ProxyRenderer(world, surface="ellipsoids", stiffness=800.0, f_max=30.0, device_shading=0.0)
    for k in range(3000):
        f2 = plain.render((0.0, 0.0, 2.0 - 0.001 * k), (r, r, r), (0.0, 0.0, -1.0), 1e-3)
    assert plain.proxy[2] > z_touch - 0.15 and f2[2] > 0
    with pytest.raises(ValueError):
        gshaptics.ProxyRenderer(world, device_shading=-0.1)
    # The corner normal off: the roof (a face, no corner) holds the same way.
    shaded = gshaptics.ProxyRenderer(world, surface="ellipsoids", stiffness=800.0, f_max=30.0, corner_normal=False)
    for k in range(3000):
        f3 = shaded.render((0.0, 0.0, 2.0 - 0.001 * k), (r, r, r), (0.0, 0.0, -1.0), 1e-3)
    assert shaded.proxy[2] > z_touch - 0.15 and f3[2] > 0
    # The overhang falloff off: the roof holds the same way.
    every_disc = gshaptics.ProxyRenderer(world, surface="ellipsoids", stiffness=800.0, f_max=30.0, overhang_falloff=False)
    for k in range(3000):
        f4 = every_disc.render((0.0, 0.0, 2.0 - 0.001 * k), (r, r, r), (0.0, 0.0, -1.0), 1e-3)
    assert every_disc.proxy[2] > z_touch - 0.15 and f4[2] > 0


def test_run_probe_with_either_force_model(data_dir):
    scene = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(scene, registration=os.path.join(data_dir, "truck.registration.json"))
    proxy = world.run_probe(sites=2, tool_radius=0.05)
    paper = world.run_probe(sites=2, tool_radius=0.05, force_model="paper")
    for run in (proxy, paper):
        assert run["contacts"].max() > 0 and np.abs(run["force"]).max() > 0
    with pytest.raises(ValueError):
        world.run_probe(sites=2, force_model="spring")


def test_run_probe_defaults_match_the_cli(data_dir, scenes_dir):
    # The CLI's defaults: tool radius 1 % of the robust extent, the world's own up (here the
    # PLY's y-down convention: the probe comes down along +y, i.e. up = -y).
    scene = gshaptics.Scene.load(os.path.join(scenes_dir, "donut.ply"))
    assert scene.report["frame"] == "RDF"
    world = gshaptics.CollisionWorld(scene)
    np.testing.assert_allclose(world.up, (0, -1, 0), atol=1e-12)
    run = world.run_probe(sites=2)
    assert run["contacts"].max() > 0
    # The probe starts above the object along the world's up: its first positions have the
    # smallest y of the run (up is -y).
    assert run["position"][0, 1] < np.median(run["position"][:, 1])
    upright = gshaptics.CollisionWorld(scene, up="auto")
    np.testing.assert_allclose(upright.up, (0, 0, 1), atol=1e-9)
    assert upright.robust_extent == pytest.approx(world.robust_extent, rel=1e-5)
    with pytest.raises(ValueError):
        world.run_probe(sites=1, tool_radius=float("nan"))


def test_run_probe_desktop_profile_limits_the_force(data_dir):
    scene = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(scene, registration=os.path.join(data_dir, "truck.registration.json"))
    run = world.run_probe(sites=2, tool_radius=0.05, device_profile="desktop")
    peak = np.linalg.norm(run["force"], axis=1).max()
    assert 1.0 < peak <= 3.3 + 1e-9
    with pytest.raises(ValueError):
        world.run_probe(sites=1, device_profile="glove")


def test_compound_tool_on_the_truck_roof_gives_force_torque_and_tagged_contacts(data_dir, tmp_path):
    scene = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(scene, registration=os.path.join(data_dir, "truck.registration.json"))
    stylus = gshaptics.Tool("stylus:0.4,0.03")
    assert len(stylus) == 4 and abs(stylus.reach - 0.4) < 1e-12
    assert stylus.parts[0]["semi_axes"][2] > stylus.parts[0]["semi_axes"][0]
    with pytest.raises(ValueError, match="unknown tool 'cube'"):
        gshaptics.Tool("cube:1")
    bad = tmp_path / "tool.json"
    bad.write_text('{"parts": []}')
    with pytest.raises(ValueError, match="tool.json"):
        gshaptics.Tool(str(bad))
    # Find the roof under the TCP with a sphere, then lay the stylus over it: tilted 60 deg about
    # y, its tip 1 cm into the roof. The roof pushes the tip up and turns the stylus.
    sphere = gshaptics.Tool("sphere:0.03")
    z = 2.0
    while z > 0 and np.linalg.norm(gshaptics.PaperRenderer(world).render(
            sphere, (0.0, 0.0, z), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1e-3)["force"]) == 0:
        z -= 0.005
    assert 0.8 < z < 1.2  # the roof, about 1 m up
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    r = gshaptics.PaperRenderer(world)
    out = r.render(stylus, (0.0, 0.0, z - 0.04), (c, 0.0, s, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1e-3)
    assert out["force"][2] > 0
    assert np.linalg.norm(out["torque"]) > 0
    assert len(out["index"]) == len(out["part"]) == len(out["k_min"]) > 0
    assert set(out["part"]) <= {0, 1, 2, 3} and 0 in set(out["part"])
    # The torque is the sum over parts of lever x force, so it is perpendicular to nothing in
    # particular, but it is bounded by |F| times the stylus' reach.
    assert np.linalg.norm(out["torque"]) <= np.linalg.norm(out["force"]) * stylus.reach * 1.01
    # The proxy with the same stylus, its tip pressed from 3 cm above the roof to 3 cm into it in
    # 60 ticks: it holds the tool on the roof (above the device), pushes up, and its torque is its
    # force's moment about the TCP.
    proxy = gshaptics.ProxyRenderer(world)
    for k in range(61):
        out = proxy.render_tool(stylus, (0.0, 0.0, z - 0.001 * k), (c, 0.0, s, 0.0), (0.0, 0.0, -1.0),
                                (0.0, 0.0, 0.0), 1e-3)
    assert out["force"][2] > 1.0
    assert out["proxy"][2] > z - 0.06 + 0.01  # held well above the device
    assert len(out["part"]) > 0 and set(out["part"]) <= {0, 1, 2, 3}
    tau = np.asarray(out["torque"])
    assert np.linalg.norm(tau) > 0 and abs(np.dot(tau, out["force"])) < 1e-9 * np.linalg.norm(tau) * np.linalg.norm(out["force"]) + 1e-12
    assert np.linalg.norm(tau) <= np.linalg.norm(out["force"]) * stylus.reach * 1.01


def test_proxy_reads_a_material_map(data_dir, tmp_path):
    scene = gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"))
    world = gshaptics.CollisionWorld(scene, registration=os.path.join(data_dir, "truck.registration.json"))
    stiff = tmp_path / "roof.json"
    stiff.write_text(json.dumps({"frame": "world", "materials": [{"name": "roof", "stiffness": 2000.0}],
                                 "regions": [{"material": "roof", "box": {"min": [-5, -5, -5], "max": [5, 5, 5]}}]}))
    r = 0.03
    forces = []
    for kwargs in ({}, {"materials": str(stiff)}):
        proxy = gshaptics.ProxyRenderer(world, stiffness=800.0, **kwargs)
        for k in range(1100):  # from 2 m down to 0.9 m: about 0.1 m past the roof, ~1 m up
            f = proxy.render((0.0, 0.0, 2.0 - 0.001 * k), (r, r, r), (0.0, 0.0, 0.0), 1e-3)  # (no damping term)
        forces.append(np.linalg.norm(f))
        if kwargs:
            assert proxy.material["name"] == "roof" and proxy.material["stiffness"] == 2000.0
    assert forces[0] > 2.0
    np.testing.assert_allclose(forces[1] / forces[0], 2000.0 / 800.0, rtol=0.02)
    bad = tmp_path / "bad.json"
    bad.write_text('{"materials": [{"name": "a", "stifness": 1}], "regions": []}')
    with pytest.raises(gshaptics.InputError, match="bad.json.*unknown key"):
        gshaptics.ProxyRenderer(world, materials=str(bad))


def test_colour_regions_select_by_the_scene_colour(data_dir, tmp_path):
    # A colour region needs the scene's colour: a world built from a scene loaded without it refuses
    # the map, naming it; with it, a tolerance wide enough for every colour claims the roof.
    everything = tmp_path / "colour.json"
    everything.write_text(json.dumps({"materials": [{"name": "any", "stiffness": 2000.0}],
                                      "regions": [{"material": "any", "colour": {"rgb": [0.5, 0.5, 0.5], "tolerance": 2.0}}]}))
    reg = os.path.join(data_dir, "truck.registration.json")
    plain = gshaptics.CollisionWorld(gshaptics.Scene.load(os.path.join(data_dir, "truck.splat")), registration=reg)
    with pytest.raises(gshaptics.InputError, match="colour.json.*no colour"):
        gshaptics.ProxyRenderer(plain, materials=str(everything))
    coloured = gshaptics.CollisionWorld(gshaptics.Scene.load(os.path.join(data_dir, "truck.splat"), keep_color=True),
                                        registration=reg)
    proxy = gshaptics.ProxyRenderer(coloured, stiffness=800.0, materials=str(everything))
    for k in range(1100):
        proxy.render((0.0, 0.0, 2.0 - 0.001 * k), (0.03, 0.03, 0.03), (0.0, 0.0, 0.0), 1e-3)
    assert proxy.material["name"] == "any" and proxy.material["stiffness"] == 2000.0


def test_push_scenario_slides_the_box_at_its_friction():
    """The push scenario from Python: the box slides and the friction felt while it slides is
    mu m g within 5 %; a heavier box is harder to push (its friction felt grows with m)."""
    if not hasattr(gshaptics, "push_scenario"):
        pytest.skip("built without rigid objects (libmujoco-dev)")
    light = gshaptics.push_scenario()
    heavy = gshaptics.push_scenario(mass=0.8, friction=0.5)
    for r in (light, heavy):
        assert r["time"].shape[0] == r["object_position"].shape[0] > 1000
        assert r["object_position"].shape[1] == 3
        assert r["travelled"] > 0.05
        assert abs(r["friction_felt"] / r["friction_expected"] - 1) < 0.05
        assert r["deepest_box_depth"] < 1e-3  # the tool at its proxy under 1 mm into the box (either surface)
        assert r["lowest_energy"] >= -1e-6
    assert heavy["friction_expected"] == pytest.approx(0.8 * 0.5 * 9.81)
    assert heavy["friction_felt"] > 2 * light["friction_felt"]


def test_object_scene_pushes_a_box_and_reports_its_pose_and_wrench(tmp_path):
    """A scene with a rigid object from Python (issue 72): a sphere pushed along +x into a box of
    Gaussians cut from `synth box-on-floor` moves the box; the poses say where it went, and the
    hand's wrench on it pushes along +x while the hand feels the opposite."""
    if not hasattr(gshaptics, "ObjectScene"):
        pytest.skip("built without rigid objects (libmujoco-dev)")
    cli = os.environ.get("GSHAPTICS_CLI")
    if not cli:
        pytest.skip("GSHAPTICS_CLI not set (run through ctest)")
    path = str(tmp_path / "box_on_floor.ply")
    out = subprocess.run([cli, "synth", "box-on-floor", path, "--spacing", "0.01"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    spec = out.stdout.split("--object ")[1].split()[0]
    scene = gshaptics.ObjectScene(gshaptics.Scene.load(path), [spec + ":mass=0.2:friction=0.3"], up="z-up")
    assert len(scene) == 1 and scene.static_size > 0
    np.testing.assert_allclose(scene.rest_origins[0], [0.0, 0.0, 0.03], atol=1e-3)
    dt, speed = 1e-3, 0.1
    pushing, weights = [], []
    for k in range(1500):  # from x = -0.1 to +0.05 at mid-height of the box
        x = -0.1 + speed * dt * k
        r = scene.render((x, 0.0, 0.03), 0.01, (speed, 0.0, 0.0), dt)
        p = scene.poses()
        weights.append(r["whole_scene_weight"])
        if p["wrench_force"][0, 0] > 0:
            pushing.append((r["force"][0], p["wrench_force"][0, 0]))
    # Felt through the whole scene while the box stood, through its own proxy once it slid.
    assert max(weights) == 1.0 and weights[-1] == 0.0
    p = scene.poses()
    assert p["time"] == pytest.approx(1.5, abs=2e-3)
    assert p["position"].shape == (1, 3) and p["rotation"].shape == (1, 4)
    assert p["position"][0, 0] > 0.03  # pushed about 5 cm along +x
    assert abs(p["position"][0, 1]) < 0.01 and abs(p["position"][0, 2] - 0.03) < 0.003
    assert len(pushing) > 500
    hand, on_box = np.array(pushing).T
    assert (hand < 0).mean() > 0.9  # the hand feels the box push back
    assert np.median(on_box) > 0.3 * 0.2 * 9.81 * 0.8  # enough to overcome mu m g, within the ramp
    scene.reset()
    np.testing.assert_allclose(scene.poses()["position"][0], scene.rest_origins[0], atol=1e-3)
    with pytest.raises(ValueError, match="unknown cut"):
        gshaptics.ObjectScene(gshaptics.Scene.load(path), ["sphere:1"])
    # The floor as a static support (its hull): the box stands on it, still, where it was.
    held = gshaptics.ObjectScene(gshaptics.Scene.load(path), [spec], up="z-up",
                                 supports=["box:-0.3,-0.3,-0.05,0.3,0.3,-0.0003"])
    for _ in range(300):
        held.render((0.0, 0.0, 0.5), 0.01, (0.0, 0.0, 0.0), 1e-3)
    np.testing.assert_allclose(held.poses()["position"][0, :2], [0.0, 0.0], atol=1e-3)
    assert abs(held.poses()["position"][0, 2] - 0.03) < 0.006
    # It stands: untouched it stays (a concave cut in pieces, hulls=2, the same for a box).
    pieces = gshaptics.ObjectScene(gshaptics.Scene.load(path), [spec + ":hulls=2"], up="z-up")
    drift = pieces.untouched_drift(1.0)
    assert drift["moved"][0] < 0.01 and drift["turned"][0] < 0.09
    assert pieces.mjcf().count("<freejoint/>") == 1 and "mesh='hull0'" in pieces.mjcf()  # a box stays one piece
