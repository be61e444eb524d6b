// Rigid objects (issue 72): the spec, the cut, the body-frame query against the reference, and
// the MuJoCo dynamics against the analytic answers of a pushed box (slide at mu m g, accelerate
// at (F - mu m g) / m, tip at m g d / h).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <cmath>
#include <fstream>
#include <random>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/error.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/io/scene_writer.h"
#include "gshaptics/objects/object_dynamics.h"
#include "gshaptics/objects/object_renderer.h"
#include "gshaptics/objects/push_scenario.h"
#include "support/allocation_counter.h"
#include "support/reference.h"

#include <mujoco/mujoco.h>

namespace gshaptics {
namespace {

constexpr double kG = 9.81;

RigidObject box_object(const Eigen::Vector3d& half, double mass, double mu) {
  ObjectSpec spec;
  spec.mass = mass;
  spec.friction = mu;
  spec.text = "test box";
  return make_rigid_object(box_surface_gaussians(Eigen::Vector3d(0, 0, half.z()), half, 0.01), spec, WorldConfig{});
}

TEST(ObjectSpec, ParsesBoxesIndicesAndProperties) {
  const ObjectSpec box = parse_object_spec("box:0.1,-1,0,-0.1,1,2:mass=0.25:friction=0.7");
  EXPECT_EQ(box.cut, ObjectSpec::Cut::kBox);
  EXPECT_DOUBLE_EQ(box.box_lo.x(), -0.1);
  EXPECT_DOUBLE_EQ(box.box_hi.x(), 0.1);
  EXPECT_DOUBLE_EQ(box.box_hi.z(), 2);
  EXPECT_DOUBLE_EQ(box.mass, 0.25);
  EXPECT_DOUBLE_EQ(box.friction, 0.7);
  const ObjectSpec ids = parse_object_spec("indices:5,3,5,9");
  EXPECT_EQ(ids.indices, (std::vector<std::uint32_t>{3, 5, 9}));
  EXPECT_DOUBLE_EQ(ids.mass, kDefaultObjectMass);
  for (const char* bad : {"box:1,2,3", "box:0,0,0,1,1,1:mass=-1", "sphere:1", "indices:1,x", "box:0,0,0,1,1,1:spin=2",
                          "box:0,0,0,0,1,1"}) {
    try {
      (void)parse_object_spec(bad, "--object");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--object '"), std::string::npos) << e.what();
    }
  }
}

TEST(SceneCut, TheBoxTakesTheGaussiansInsideItAndNoOthers) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianScene scene;
  for (std::uint32_t i = 0; i < 4000; ++i)
    scene.push_back(Eigen::Vector3f(u(rng), u(rng), u(rng)), Eigen::Vector3f::Constant(0.02f),
                    Eigen::Vector4f(1, 0, 0, 0), 0.2f + 0.7f * (u(rng) + 1) / 2, i);
  SimilarityTransform T;
  T.scale = 2;
  T.translation = Eigen::Vector3d(0.5, 0, 0);
  ObjectSpec spec = parse_object_spec("box:0,0,0,1,1,1");
  const SceneCut cut = cut_objects(scene, T, std::span<const ObjectSpec>(&spec, 1), 0.2f);
  ASSERT_EQ(cut.objects.size(), 1u);
  EXPECT_EQ(cut.rest.size() + cut.objects[0].size(), scene.size());
  std::vector<bool> in_object(scene.size(), false);
  for (std::size_t k = 0; k < cut.objects[0].size(); ++k) {
    const std::uint32_t i = cut.objects[0].source_index[k];
    in_object[i] = true;
    // Moved into the world: the mean and the scale.
    EXPECT_NEAR((cut.objects[0].means[k].cast<double>() - T.apply(scene.means[i].cast<double>())).norm(), 0, 1e-6);
    EXPECT_NEAR(cut.objects[0].scales[k].x(), 0.04f, 1e-6);
  }
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const Eigen::Vector3d c = T.apply(scene.means[i].cast<double>());
    const bool inside = (c.array() >= 0).all() && (c.array() <= 1).all();
    EXPECT_EQ(in_object[i], inside) << i;
  }
  // The static world's contacts away from the box are the whole scene's.
  WorldConfig cfg;
  cfg.registration = T;
  const CollisionWorld whole = CollisionWorld::build(scene, cfg), rest = CollisionWorld::build(cut.rest, cfg);
  ContactQuery qa(whole), qb(rest);
  for (const Eigen::Vector3d& c : {Eigen::Vector3d(-0.5, -0.5, -0.5), Eigen::Vector3d(2, -1, 0.5)}) {
    const ToolEllipsoid tool = ToolEllipsoid::sphere(c, 0.15);
    qa.run(tool);
    qb.run(tool);
    auto ids = [](std::span<const Contact> cs) {
      std::vector<std::uint32_t> v;
      for (const Contact& x : cs) v.push_back(x.index);
      std::sort(v.begin(), v.end());
      return v;
    };
    EXPECT_GT(qa.result().contacts().size(), 0u);
    EXPECT_EQ(ids(qa.result().contacts()), ids(qb.result().contacts()));
  }
  EXPECT_THROW((void)cut_objects(scene, T, std::span<const ObjectSpec>(std::vector<ObjectSpec>{parse_object_spec("box:9,9,9,10,10,10")}), 0.2f),
               InputError);
}

TEST(RigidObject, TheQueryInTheBodyFrameMatchesTheReferenceOnTheMovedGaussians) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianScene g;
  for (std::uint32_t i = 0; i < 600; ++i) {
    Eigen::Vector4f q(u(rng), u(rng), u(rng), u(rng));
    g.push_back(Eigen::Vector3f(0.3f + 0.1f * u(rng), 0.1f * u(rng), 0.2f + 0.1f * u(rng)),
                Eigen::Vector3f(0.004f + 0.003f * u(rng), 0.01f + 0.004f * u(rng), 0.002f + 0.001f * u(rng)),
                q.normalized(), 0.5f + 0.4f * u(rng), i);
  }
  ObjectSpec spec;
  spec.text = "cloud";
  const RigidObject object = make_rigid_object(g, spec, WorldConfig{});
  ContactQuery query(*object.body);
  int compared = 0;
  for (int trial = 0; trial < 12; ++trial) {
    BodyPose pose;
    pose.rotation = Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized());
    pose.position = Eigen::Vector3d(u(rng), u(rng), u(rng));
    // The Gaussians moved by the pose: x = R (x_world_rest - origin) + p.
    SimilarityTransform moved;
    moved.rotation = pose.rotation;
    moved.translation = pose.position - (pose.rotation * object.rest_origin);
    const auto reference = test::reference_world(g, WorldConfig{}.min_opacity, 1.0, moved);
    ToolEllipsoid tool;
    tool.semi_axes = Eigen::Vector3d(0.03, 0.015, 0.02);
    tool.rotation = Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized());
    tool.center = pose.position + pose.rotation * Eigen::Vector3d(0.06 * u(rng), 0.06 * u(rng), 0.06 * u(rng));
    ToolEllipsoid body_tool = tool;
    body_tool.center = pose.rotation.conjugate() * (tool.center - pose.position);
    body_tool.rotation = pose.rotation.conjugate() * tool.rotation;
    ASSERT_EQ(query.run(body_tool), QueryStatus::kOk);
    std::vector<test::RefContact> near;
    const auto expected = test::reference_contacts(reference, tool, 1e-6, &near);
    std::vector<Contact> got(query.result().contacts().begin(), query.result().contacts().end());
    std::sort(got.begin(), got.end(), [](const Contact& a, const Contact& b) { return a.index < b.index; });
    // Grazing pairs (|K_min| <= 1e-6) may go either way; every other one must agree.
    auto grazing = [&](std::uint32_t i) {
      return std::any_of(near.begin(), near.end(), [&](const test::RefContact& r) { return r.index == i; });
    };
    std::size_t k = 0;
    for (const test::RefContact& r : expected) {
      while (k < got.size() && got[k].index < r.index) {
        EXPECT_TRUE(grazing(got[k].index)) << "extra contact " << got[k].index;
        ++k;
      }
      if (k < got.size() && got[k].index == r.index) {
        EXPECT_NEAR(got[k].k_min, r.k_min, 1e-4);
        ++compared;
        ++k;
      } else {
        EXPECT_TRUE(grazing(r.index)) << "missed contact " << r.index;
      }
    }
  }
  EXPECT_GT(compared, 30);
}

// Pushes object 0 with `force` (N, world) at its centre of mass for `seconds` after 0.3 s at
// rest; returns its displacement along the push (m) and its acceleration over the last `window`
// s (m/s^2): twice the quadratic coefficient of a least-squares fit of the displacement, which
// averages over the rocking of a box on a few contact points.
struct PushResult {
  double displacement = 0, acceleration = 0;
};
PushResult push(ObjectDynamics& d, const Eigen::Vector3d& force, double seconds, double window) {
  const double h = d.params().timestep;
  for (int k = 0; k < int(0.3 / h); ++k) d.step();  // settle on the plane
  const Eigen::Vector3d dir = force.normalized(), x0 = d.pose(0).position;
  const int n = int(std::round(seconds / h)), n_window = int(std::round(window / h));
  Eigen::MatrixXd A(n_window, 3);
  Eigen::VectorXd x(n_window);
  for (int k = 0; k < n; ++k) {
    d.apply_wrench(0, force, d.center_of_mass(0));
    d.step();
    if (const int row = k - (n - n_window); row >= 0) {
      const double t = row * h;
      A.row(row) << 1, t, t * t;
      x[row] = (d.pose(0).position - x0).dot(dir);
    }
  }
  const Eigen::Vector3d fit = A.colPivHouseholderQr().solve(x);
  return {(d.pose(0).position - x0).dot(dir), 2 * fit[2]};
}

TEST(ObjectDynamics, ABoxSlidesOnlyPastMuMgThenAcceleratesAtTheRemainder) {
  double worst = 0;  // relative error of the acceleration
  for (const double mu : {0.3, 0.6}) {
    const RigidObject box = box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, mu);
    const std::vector<RigidObject> objects{box};
    const SupportPlane plane = support_under(objects, Eigen::Vector3d::UnitZ());
    for (const double ratio : {0.9, 0.95, 1.05, 1.5, 2.0}) {
      ObjectDynamics d(objects, plane);
      const double m = d.mass(0);
      EXPECT_NEAR(m, 0.4, 1e-9);
      const double F = ratio * mu * m * kG;
      const PushResult r = push(d, Eigen::Vector3d(F, 0, 0), 0.4, 0.2);
      SCOPED_TRACE(testing::Message() << "mu " << mu << " F/(mu m g) " << ratio);
      if (ratio < 1) {
        EXPECT_LT(std::abs(r.displacement), 1e-3);
      } else {
        EXPECT_GT(r.displacement, 2e-3);
      }
      if (ratio >= 1.5) {
        const double expected = (F - mu * m * kG) / m;
        EXPECT_NEAR(r.acceleration, expected, 0.05 * expected);
        worst = std::max(worst, std::abs(r.acceleration / expected - 1));
      }
    }
  }
  RecordProperty("worst_acceleration_error", std::to_string(worst));
}

TEST(ObjectDynamics, ABoxAtRestSleepsWithoutMovingAndAPushWakesIt) {
  const std::vector<RigidObject> objects{box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.3)};
  ObjectDynamics d(objects, support_under(objects, Eigen::Vector3d::UnitZ()));
  int slept = 0;
  for (int k = 0; k < 1000; ++k) {
    d.step();
    slept += d.asleep();
  }
  EXPECT_GT(slept, 500) << "a box at rest on the plane never slept";
  const Eigen::Vector3d rest = d.pose(0).position;
  EXPECT_LT((rest - objects[0].rest_origin).norm(), 1e-3);  // it settled where it stood
  EXPECT_NEAR(d.time(), 1.0, 1e-9);                         // sleeping steps keep the time
  // A push above mu m g wakes it and it slides.
  for (int k = 0; k < 200; ++k) {
    d.apply_wrench(0, Eigen::Vector3d(2 * 0.3 * 0.4 * kG, 0, 0), d.center_of_mass(0));
    d.step();
    EXPECT_FALSE(d.asleep());
  }
  EXPECT_GT(d.pose(0).position.x() - rest.x(), 0.01);
}

// What readers get: every subscribed reader sees each step's poses and the wrench the hand put
// on the object over that step; the track logs one row per published step (none while asleep),
// and when the hand lets go of a sleeping object the readers see the wrench go to zero.
TEST(ObjectPoseChannel, ReadersAndTheTrackSeeEachStepsPoseAndTheAppliedWrench) {
  const std::vector<RigidObject> objects{box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.3)};
  auto channel = std::make_shared<ObjectPoseChannel>();
  const int viewer = channel->subscribe(), ros = channel->subscribe();
  ASSERT_EQ(viewer, 0);
  ASSERT_EQ(ros, 1);
  channel->record_into(std::make_shared<ObjectTrack>(1, 100000));
  ObjectDynamics d(objects, support_under(objects, Eigen::Vector3d::UnitZ()), {}, channel);
  ObjectPoses seen;
  ASSERT_TRUE(channel->read_if_new(viewer, seen));  // the rest pose, published at construction
  EXPECT_EQ(seen.count, 1u);
  EXPECT_LT((seen.poses[0].position - objects[0].rest_origin).norm(), 1e-3);
  for (int k = 0; k < 300; ++k) d.step();  // settles, then sleeps
  ASSERT_TRUE(d.asleep());
  const std::size_t rows_asleep = channel->track()->rows();
  for (int k = 0; k < 100; ++k) d.step();
  EXPECT_EQ(channel->track()->rows(), rows_asleep) << "a sleeping step logged a row";
  // A push above mu m g at the centre of mass: the readers see the force and the box moving.
  const Eigen::Vector3d F(2 * 0.3 * 0.4 * kG, 0, 0);
  for (int k = 0; k < 100; ++k) {
    d.apply_wrench(0, F, d.center_of_mass(0));
    d.step();
  }
  ASSERT_TRUE(channel->read_if_new(ros, seen));
  EXPECT_NEAR((seen.wrenches[0].force - F).norm(), 0, 1e-9);
  EXPECT_LT(seen.wrenches[0].torque.norm(), 1e-9);
  EXPECT_GT(seen.poses[0].position.x() - objects[0].rest_origin.x(), 1e-3);
  EXPECT_NEAR(seen.poses[0].position.x(), d.pose(0).position.x(), 1e-12);
  const ObjectTrack& track = *channel->track();
  EXPECT_EQ(track.rows(), rows_asleep + 100);
  EXPECT_NEAR(track.position(track.rows() - 1, 0).x(), d.pose(0).position.x(), 1e-6);
  EXPECT_NEAR(track.force(track.rows() - 1, 0).x(), F.x(), 1e-5);
  // Let go: it slides to a stop and sleeps; the readers' last value has no wrench.
  for (int k = 0; k < 2000; ++k) d.step();
  ASSERT_TRUE(channel->read_if_new(viewer, seen));
  EXPECT_EQ(seen.wrenches[0].force.norm(), 0.0);
  EXPECT_FALSE(channel->read_if_new(viewer, seen)) << "nothing new was published";
  // A reader that comes after the last write still gets the newest value (the dynamics only
  // step while the device sends poses: a viewer opened meanwhile must see where the box is).
  const int late = channel->subscribe();
  ASSERT_GE(late, 0);
  ASSERT_TRUE(channel->read_if_new(late, seen));
  EXPECT_EQ(seen.poses[0].position, d.pose(0).position);
  // At most kMaxReaders readers; a reader slot never given reads nothing.
  EXPECT_GE(channel->subscribe(), 0);
  EXPECT_EQ(channel->subscribe(), -1);
  EXPECT_FALSE(channel->read_if_new(7, seen));
  // The CSV: a header naming each object's columns, one row per logged step.
  const std::string csv = testing::TempDir() + "/objects_log.csv";
  track.write_csv(csv);
  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "time_s,obj0_x,obj0_y,obj0_z,obj0_qw,obj0_qx,obj0_qy,obj0_qz,obj0_fx,obj0_fy,obj0_fz");
  std::size_t lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  EXPECT_EQ(lines, track.rows());
}

// An oriented box (obox: centre, half extents, rotation) takes the Gaussians inside it as turned,
// on the command line and in the JSON alike: a box turned 45 degrees about z takes a point on its
// diagonal that the axis-aligned box of the same extents would leave out, and not the reverse.
TEST(ObjectSpec, AnOrientedBoxTakesWhatIsInsideItAsTurned) {
  const double s = std::sqrt(0.5);
  const ObjectSpec o = parse_object_spec("obox:1,0,0,0.2,0.05,0.1," + std::to_string(std::cos(M_PI / 8)) + ",0,0," +
                                         std::to_string(std::sin(M_PI / 8)));
  GaussianScene scene;
  const Eigen::Vector3f along(float(1 + 0.15 * s), float(0.15 * s), 0.f);  // on the box's long axis, turned
  const Eigen::Vector3f across(1.15f, 0.f, 0.f);                            // along world x: outside it
  scene.push_back(along, Eigen::Vector3f::Constant(0.01f), Eigen::Vector4f(1, 0, 0, 0), 0.9f, 0);
  scene.push_back(across, Eigen::Vector3f::Constant(0.01f), Eigen::Vector4f(1, 0, 0, 0), 0.9f, 1);
  const SceneCut cut = cut_objects(scene, SimilarityTransform{}, std::span<const ObjectSpec>(&o, 1), 0.2f);
  ASSERT_EQ(cut.objects[0].size(), 1u);
  EXPECT_EQ(cut.objects[0].source_index[0], 0u);
  const std::vector<ObjectSpec> json = parse_object_specs_json(
      R"({"objects": [{"obox": {"center": [1, 0, 0], "half": [0.2, 0.05, 0.1], "rotation": [0.9238795325, 0, 0, 0.3826834324]}}]})",
      "objects.json", "").objects;
  const SceneCut cut_json = cut_objects(scene, SimilarityTransform{}, json, 0.2f);
  ASSERT_EQ(cut_json.objects[0].size(), 1u);
  EXPECT_EQ(cut_json.objects[0].source_index[0], 0u);
  EXPECT_THROW((void)parse_object_spec("obox:1,0,0,0.2,0.05,0.1,0,0,0,0"), InputError);
  EXPECT_THROW((void)parse_object_spec("obox:1,0,0,0.2,0,0.1,1,0,0,0"), InputError);
  EXPECT_THROW((void)parse_object_spec("obox:1,0,0"), InputError);
}

// An object from a splat file of its own: placed in the world by its registration (and --up as
// the scene is), its colour kept; the cut leaves the scene whole for it; bad specs and files
// are errors that name them.
TEST(SceneCut, AFileObjectIsPlacedByItsOwnRegistration) {
  GaussianScene box = box_surface_gaussians(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.05, 0.04, 0.03), 0.01);
  box.colors_dc.assign(box.size(), Eigen::Vector3f(1, 0, 0));
  const std::string dir = testing::TempDir();
  const std::string ply = dir + "/file_object.ply", reg = dir + "/file_object_reg.json";
  write_scene(ply, box);
  {
    std::ofstream(reg) << R"({"scale": 2, "translation": [1, 0, 0.5]})";
  }
  const ObjectSpec spec = parse_object_spec("file:" + ply + ":registration=" + reg + ":mass=0.3");
  EXPECT_EQ(spec.cut, ObjectSpec::Cut::kFile);
  EXPECT_EQ(spec.file, ply);
  EXPECT_EQ(spec.registration_file, reg);
  EXPECT_EQ(spec.mass, 0.3);
  const GaussianScene placed = object_from_file(spec, UpAxis::kNone, 0.2f);
  ASSERT_EQ(placed.size(), box.size());
  for (std::size_t i = 0; i < box.size(); i += 37) {
    EXPECT_NEAR((placed.means[i].cast<double>() - (2 * box.means[i].cast<double>() + Eigen::Vector3d(1, 0, 0.5))).norm(), 0, 1e-6);
    EXPECT_NEAR(placed.scales[i].x(), 2 * box.scales[i].x(), 1e-6);
  }
  ASSERT_EQ(placed.colors_dc.size(), placed.size());
  EXPECT_NEAR(placed.colors_dc[0].x(), 1.0f, 1e-6);
  // Beside a scene: the cut claims none of the scene's Gaussians for it; load_file_objects fills it.
  const GaussianScene scene = box_surface_gaussians(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.2, 0.2, 0.01), 0.02);
  const std::vector<ObjectSpec> specs{spec};
  SceneCut cut = cut_objects(scene, SimilarityTransform{}, specs, 0.2f);
  EXPECT_EQ(cut.rest.size(), scene.size());
  EXPECT_TRUE(cut.objects[0].empty());
  load_file_objects(cut, specs, UpAxis::kNone, 0.2f);
  EXPECT_EQ(cut.objects[0].size(), box.size());
  EXPECT_THROW((void)parse_object_spec("box:0,0,0,1,1,1:registration=" + reg), InputError);
  EXPECT_THROW((void)parse_object_spec("file:"), InputError);
  try {
    (void)object_from_file(parse_object_spec("file:" + dir + "/missing.ply"), UpAxis::kNone, 0.2f);
    FAIL() << "a missing file loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.ply"), std::string::npos) << e.what();
  }
}

// A MuJoCo error (here its stack overflowing: a model given far too small a stack) does not end
// the process, as MuJoCo's default handler would with the device wherever it is: the dynamics
// stop, the objects stay where they were, the error is counted and its message kept.
TEST(ObjectDynamics, AMuJoCoErrorStopsTheDynamicsNotTheProcess) {
  const std::vector<RigidObject> objects{box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.3)};
  const SupportPlane plane = support_under(objects, Eigen::Vector3d::UnitZ());
  // The smallest stack MuJoCo's compiler accepts (it checks the model with its own handler, and a
  // model it rejects is an InputError naming MuJoCo's message): too small for a step in contact.
  DynamicsParams p;
  std::unique_ptr<ObjectDynamics> d;
  for (p.stack = 100; !d && p.stack < 5000; p.stack += 10) {
    try {
      d = std::make_unique<ObjectDynamics>(objects, plane, p);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("MuJoCo"), std::string::npos) << e.what();
    }
  }
  ASSERT_TRUE(d) << "no stack size was accepted";
  const long before = ObjectDynamics::errors();
  const Eigen::Vector3d rest = d->pose(0).position;
  for (int k = 0; k < 10; ++k) {
    d->apply_wrench(0, Eigen::Vector3d(5, 0, 0), d->center_of_mass(0));
    d->step();
  }
  ASSERT_TRUE(d->failed()) << "a stack of " << p.stack - 10 << " mjtNums did not overflow";
  EXPECT_EQ(ObjectDynamics::errors(), before + 1);  // one error, then no more steps
  EXPECT_NE(ObjectDynamics::last_error().find("tack"), std::string::npos) << ObjectDynamics::last_error();
  EXPECT_NEAR(d->time(), 0.01, 1e-9);  // the time goes on
  EXPECT_LT((d->pose(0).position - rest).norm(), 1e-3);  // the box stays where it was
  // A model with MuJoCo's own stack is unaffected.
  ObjectDynamics fine(objects, plane);
  for (int k = 0; k < 10; ++k) {
    fine.apply_wrench(0, Eigen::Vector3d(5, 0, 0), fine.center_of_mass(0));
    fine.step();
  }
  EXPECT_FALSE(fine.failed());
}

// A static support (a table top's hull) carries a box near its edge 30 cm over the floor; pushed
// past the edge, the box falls to the floor plane and comes to rest on it.
TEST(ObjectDynamics, ABoxPushedOffATableTopFallsToTheFloor) {
  ObjectSpec spec;
  spec.mass = 0.4;
  spec.friction = 0.3;
  spec.text = "box on the table";
  const Eigen::Vector3d half(0.05, 0.04, 0.03);
  const std::vector<RigidObject> objects{make_rigid_object(
      box_surface_gaussians(Eigen::Vector3d(0.12, 0, 0.3 + half.z()), half, 0.01), spec, WorldConfig{})};
  const RigidObject table = make_rigid_object(
      box_surface_gaussians(Eigen::Vector3d(0, 0, 0.29), Eigen::Vector3d(0.2, 0.2, 0.01), 0.01), spec, WorldConfig{});
  SupportPlane support;  // the floor at z = 0, and the table top
  std::vector<Eigen::Vector3d>& hull = support.hulls.emplace_back();
  for (const Eigen::Vector3d& p : table.hull_points) hull.push_back(table.rest_origin + p);
  ObjectDynamics d(objects, support);
  const Eigen::Quaterniond start = d.pose(0).rotation;
  for (int k = 0; k < 300; ++k) d.step();
  // It rests with its hull's lowest point on the table hull's top (both hulls reach past the
  // faces by the side discs' in-plane tips).
  double top = -1, under = 1;
  for (const Eigen::Vector3d& p : hull) top = std::max(top, p.z());
  for (const Eigen::Vector3d& p : objects[0].hull_points) under = std::min(under, objects[0].rest_origin.z() + p.z());
  EXPECT_NEAR(d.center_of_mass(0).z(), top + (0.3 + half.z() - under), 1e-3) << "the table top does not carry the box";
  EXPECT_LT(d.pose(0).rotation.angularDistance(start), 1e-3) << "the box turns on the table by itself";
  for (int k = 0; k < 600; ++k) {  // pushed along +x at twice mu m g until it is past the edge
    if (d.pose(0).position.x() < 0.3) d.apply_wrench(0, Eigen::Vector3d(2 * 0.3 * 0.4 * kG, 0, 0), d.center_of_mass(0));
    d.step();
  }
  for (int k = 0; k < 1500; ++k) d.step();
  EXPECT_GT(d.pose(0).position.x(), 0.2);
  EXPECT_LT(d.center_of_mass(0).z(), 0.1) << "the box did not fall off the table";
  EXPECT_GT(d.center_of_mass(0).z(), 0.0) << "the box fell through the floor";
}

// An arch of Gaussians (two legs 2 x 4 x 8 cm, 12 cm apart, under a 16 x 4 x 2 cm lintel),
// standing on z = 0, as one object of `hulls` convex pieces; the legs' and the lintel's Gaussians
// are told by their centres (x beyond 5 cm: a leg; z above 8 cm: the lintel).
RigidObject arch_object(int hulls) {
  GaussianScene g;
  for (const auto& [c, h] : {std::pair{Eigen::Vector3d(-0.06, 0, 0.04), Eigen::Vector3d(0.01, 0.02, 0.04)},
                             std::pair{Eigen::Vector3d(0.06, 0, 0.04), Eigen::Vector3d(0.01, 0.02, 0.04)},
                             std::pair{Eigen::Vector3d(0, 0, 0.09), Eigen::Vector3d(0.08, 0.02, 0.01)}}) {
    const GaussianScene part = box_surface_gaussians(c, h, 0.005);
    for (std::size_t i = 0; i < part.size(); ++i) g.push_back_from(part, i);
  }
  ObjectSpec spec;
  spec.mass = 0.6;
  spec.friction = 0.5;
  spec.hulls = hulls;
  spec.text = "arch";
  return make_rigid_object(g, spec, WorldConfig{});
}

// A concave object in a few convex pieces (issue 72, item 3): the cuts keep each leg and the
// lintel apart, the pieces together weigh the object's mass, and a box resting under the arch
// stays where it is. As one hull, the arch's hull would hold the box inside it, and MuJoCo
// throws the two apart.
TEST(ObjectDynamics, AnArchInPiecesLeavesRoomForABoxUnderIt) {
  const RigidObject pieces = arch_object(3);
  ASSERT_EQ(pieces.piece_ends.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {  // each piece one of the three parts (a leg may take the
    // strip of the lintel's underside next to it, which meets it at a concave edge)
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3d& p : pieces.piece(k)) box.extend(pieces.rest_origin + p);
    const bool left = box.max().x() < -0.03, right = box.min().x() > 0.03, lintel = box.min().z() > 0.075;
    EXPECT_TRUE(left || right || lintel) << "piece " << k << " spans [" << box.min().transpose() << "] to ["
                                         << box.max().transpose() << "]";
  }
  ObjectSpec spec;
  spec.mass = 0.2;
  spec.friction = 0.5;
  spec.text = "box under the arch";
  const RigidObject box =
      make_rigid_object(box_surface_gaussians(Eigen::Vector3d(0, 0, 0.02), Eigen::Vector3d(0.02, 0.02, 0.02), 0.005),
                        spec, WorldConfig{});
  SupportPlane floor;  // z = 0
  double moved[2] = {0, 0};
  for (const int hulls : {3, 1}) {
    const std::vector<RigidObject> objects{arch_object(hulls), box};
    ObjectDynamics d(objects, floor);
    EXPECT_NEAR(d.mass(0), 0.6, 1e-9);
    const Eigen::Vector3d arch = d.pose(0).position, under = d.pose(1).position;
    for (int k = 0; k < 500; ++k) d.step();
    moved[hulls == 1] = std::max((d.pose(0).position - arch).norm(), (d.pose(1).position - under).norm());
  }
  EXPECT_LT(moved[0], 2e-3) << "the arch of pieces or the box under it moved";
  EXPECT_GT(moved[1], 1e-2) << "the arch's one hull did not hold the box (the test shows nothing)";
}

// Several proxies on one tool push as one god-object would: side by side on one flat surface
// once (the deeper), at a corner and when squeezed both, at 45 degrees just as far as each asks;
// the hand's force never jumps as the forces turn or grow past each other.
TEST(ObjectRenderer, LoadSharesPushOnceAlongOneDirection) {
  const auto shares = [](std::vector<Eigen::Vector3d> f) {
    std::vector<double> s(f.size());
    load_shares(f, s);
    return s;
  };
  const auto hand = [&](const std::vector<Eigen::Vector3d>& f) {
    const std::vector<double> s = shares(f);
    Eigen::Vector3d h = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < f.size(); ++i) h += s[i] * f[i];
    return h;
  };
  const Eigen::Vector3d z(0, 0, 2), x(2, 0, 0);
  EXPECT_LT((hand({z, z}) - z).norm(), 1e-9);                        // a seam: once
  EXPECT_LT((hand({0.5 * z, z}) - z).norm(), 1e-9);                  // the deeper one
  EXPECT_EQ(shares({0.5 * z, z}), (std::vector<double>{0, 1}));
  EXPECT_EQ(shares({z, x}), (std::vector<double>{1, 1}));            // a corner: both
  EXPECT_EQ(shares({z, -z}), (std::vector<double>{1, 1}));           // squeezed: both (they cancel)
  EXPECT_EQ(shares({Eigen::Vector3d::Zero(), z}), (std::vector<double>{0, 1}));
  // At 45 degrees the hand is pushed exactly as far as each asks along its own direction (the
  // two planes' intersection, as one proxy on both), whichever comes first.
  const Eigen::Vector3d d = 2 * Eigen::Vector3d(1, 0, 1).normalized();
  for (const std::vector<Eigen::Vector3d>& f : {std::vector<Eigen::Vector3d>{z, d}, std::vector<Eigen::Vector3d>{d, z}}) {
    const Eigen::Vector3d h = hand(f);
    EXPECT_NEAR(h.dot(z.normalized()), 2, 1e-6);
    EXPECT_NEAR(h.dot(d.normalized()), 2, 1e-6);
  }
  // Three proxies: two side by side and one at a corner with them.
  EXPECT_LT((hand({z, 0.9 * z, x}) - (z + x)).norm(), 1e-6);
  // The hand's force as the second (of the same size, so their order flips with rounding)
  // turns from the first's direction to a right angle: from |F| = 2 to 2 sqrt 2, never a jump;
  // and as one grows past the other at 30 degrees.
  Eigen::Vector3d last = z;
  for (int k = 1; k <= 90; ++k) {
    const double a = k * M_PI / 180;
    const Eigen::Vector3d h = hand({z, 2 * Eigen::Vector3d(std::sin(a), 0, std::cos(a))});
    EXPECT_LT((h - last).norm(), 0.1) << k << " deg";
    last = h;
  }
  EXPECT_NEAR(last.norm(), 2 * std::sqrt(2.0), 1e-6);
  last = hand({z, 1.5 * Eigen::Vector3d(0.5, 0, std::sqrt(0.75))});
  for (int k = 1; k <= 100; ++k) {
    const Eigen::Vector3d h = hand({z, (1.5 + 0.01 * k) * Eigen::Vector3d(0.5, 0, std::sqrt(0.75))});
    EXPECT_LT((h - last).norm(), 0.03) << k;
    last = h;
  }
}

// Where an object was cut from a flat slab, the hand pressing across the seam feels the slab as
// it was (a ridge of twice the stiffness there before: the scene's proxy and the object's both
// pushed); away from the seam, each side as before (the object's side up to 7 % softer: it sinks
// into MuJoCo's soft contact under the press).
TEST(ObjectRenderer, TheSeamOfACutIsFeltAsTheSurfaceItWas) {
  const GaussianScene slab =
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.005), Eigen::Vector3d(0.1, 0.1, 0.005), 0.004);
  GaussianScene rest, half;
  for (std::size_t i = 0; i < slab.size(); ++i) (slab.means[i].x() > 0 ? half : rest).push_back_from(slab, i);
  ObjectSpec spec;
  spec.mass = 5;
  spec.text = "half slab";
  const std::vector<RigidObject> objects{make_rigid_object(half, spec, WorldConfig{})};
  const CollisionWorld world = CollisionWorld::build(rest, WorldConfig{}), whole = CollisionWorld::build(slab, WorldConfig{});
  auto dynamics = std::make_shared<ObjectDynamics>(objects, support_under(objects, Eigen::Vector3d::UnitZ()));
  const double R = 0.005;
  for (const double x : {-0.02, -0.003, 0.0, 0.003, 0.02}) {
    const auto cut = make_object_renderer(RendererSpec{}, world, objects, dynamics);
    const auto uncut = make_force_renderer(RendererSpec{}, whole);
    dynamics->reset();
    Eigen::Vector3d felt, was;
    for (int k = 0; k <= 300; ++k) {  // from 1 cm above the top to 2 mm into it over 0.25 s, held
      const double z = R + 0.01 - 0.012 * std::min(1.0, k / 250.0);
      const ToolEllipsoid tool = ToolEllipsoid::sphere(Eigen::Vector3d(x, 0.001, z), R);
      felt = cut->render(tool, Eigen::Vector3d(0, 0, -0.05), 1e-3).force;
      was = uncut->render(tool, Eigen::Vector3d(0, 0, -0.05), 1e-3).force;
    }
    SCOPED_TRACE(testing::Message() << "x " << x);
    EXPECT_LT(felt.z(), 1.03 * was.z()) << "a ridge at the seam";  // (it was 1.93 x before the shares)
    EXPECT_GT(felt.z(), 0.9 * was.z());  // the object's side sinks a little into its soft contact
    EXPECT_LT(std::hypot(felt.x(), felt.y()), 0.05 * felt.z());
  }
}

// `half` moved by the rigid motion that takes its rest frame (body origin `origin`) to `pose`.
GaussianScene placed(const GaussianScene& half, const Eigen::Vector3d& origin, const BodyPose& pose) {
  SimilarityTransform m;
  m.rotation = pose.rotation;
  m.translation = pose.position - pose.rotation * origin;
  GaussianScene out = half;
  for (std::size_t i = 0; i < out.size(); ++i) {
    out.means[i] = m.apply(half.means[i].cast<double>()).cast<float>();
    const Eigen::Quaterniond q = m.apply_rotation(half.rotations[i]);
    out.rotations[i] = Eigen::Vector4f(float(q.w()), float(q.x()), float(q.y()), float(q.z()));
  }
  return out;
}

// A plane drawn as trained captures leave it (discs of log-normal sizes every 8 mm, jittered and
// tilted), its side x > `cut` as an object.
struct CutPlane {
  GaussianScene plane, rest, half;
  std::vector<RigidObject> objects;
  explicit CutPlane(double cut, double mass = kDefaultObjectMass) {
    SynthParams p;
    p.spacing = 0.008;
    p.floater_share = 0;
    plane = make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), p).scene;
    for (std::size_t i = 0; i < plane.size(); ++i) (plane.means[i].x() > cut ? half : rest).push_back_from(plane, i);
    ObjectSpec spec;
    spec.mass = mass;
    spec.text = "the plane's side";
    objects.push_back(make_rigid_object(half, spec, WorldConfig{}));
  }
};

// Joining a world places a body world's records by a rigid motion: at the rest origin it gives
// back every record of the uncut world (by source index: centre to 1e-12 m, the rest bit for bit,
// the same bounds); turned and moved, the records of the Gaussians registered by that motion
// (centre to 1e-12 m, rotation to float rounding).
TEST(CollisionWorld, AJoinedWorldPlacesAPartsGaussiansByARigidMotion) {
  const CutPlane cp(0.05);
  const CollisionWorld rest = CollisionWorld::build(cp.rest, WorldConfig{});
  const RigidObject& o = cp.objects[0];
  ASSERT_GT(o.body->size(), 100u);
  ASSERT_GT(o.rest_origin.norm(), 0.05);  // the body frame is not the world's
  const auto by_source = [](const CollisionWorld& w) {
    std::vector<const CollisionGaussian*> v;
    for (const CollisionGaussian& g : w.gaussians()) v.push_back(&g);
    std::sort(v.begin(), v.end(), [](auto* x, auto* y) { return x->source_index < y->source_index; });
    return v;
  };
  const CollisionWorld::PlacedWorld at_rest{o.body.get(), o.rest_origin};
  const CollisionWorld joined = CollisionWorld::joined(rest, std::span(&at_rest, 1));
  const CollisionWorld uncut = CollisionWorld::build(cp.plane, WorldConfig{});
  const auto a = by_source(joined), b = by_source(uncut);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k]->source_index, b[k]->source_index);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(a[k]->center[j], b[k]->center[j], 1e-12);
    EXPECT_EQ(0, std::memcmp(a[k]->quaternion, b[k]->quaternion, sizeof(float) * 9)) << k;  // rotation, axes, radius, opacity
  }
  EXPECT_LT((joined.bounds_lo() - uncut.bounds_lo()).norm(), 1e-12);
  EXPECT_LT((joined.bounds_hi() - uncut.bounds_hi()).norm(), 1e-12);

  BodyPose pose;
  pose.rotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized());
  pose.position = Eigen::Vector3d(0.01, -0.02, 0.03);
  const CollisionWorld::PlacedWorld turned_part{o.body.get(), pose.position, pose.rotation};
  const CollisionWorld turned = CollisionWorld::joined(rest, std::span(&turned_part, 1));
  GaussianScene both = cp.rest;
  const GaussianScene moved = placed(cp.half, o.rest_origin, pose);
  for (std::size_t i = 0; i < moved.size(); ++i) both.push_back_from(moved, i);
  const CollisionWorld reference = CollisionWorld::build(both, WorldConfig{});
  const auto c = by_source(turned), d = by_source(reference);
  ASSERT_EQ(c.size(), d.size());
  for (std::size_t k = 0; k < c.size(); ++k) {
    ASSERT_EQ(c[k]->source_index, d[k]->source_index);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(c[k]->center[j], d[k]->center[j], 1e-7);  // float means in the reference
    const Eigen::Vector4d qc(c[k]->quaternion[0], c[k]->quaternion[1], c[k]->quaternion[2], c[k]->quaternion[3]);
    const Eigen::Vector4d qd(d[k]->quaternion[0], d[k]->quaternion[1], d[k]->quaternion[2], d[k]->quaternion[3]);
    EXPECT_GT(std::abs(qc.dot(qd)), 1 - 1e-6) << k;
  }
}

// The plane cut in two, its side standing where it settles on its support (it sinks 0.3 mm and
// tilts 0.08 degree onto its lowest discs): the hand pressing across the seam feels what one proxy
// on all the Gaussians where they stand gives (within 1 %). Each body's proxy alone rests on half
// the discs and sinks or tilts where the other half held it: the check below that they did (over
// 3 % off somewhere) keeps this test about the seam.
TEST(ObjectRenderer, AtTheSeamOfACutTheHandFeelsTheWholeScene) {
  const CutPlane cp(0.0, 1e9);  // nothing the hand does moves it
  const std::vector<RigidObject>& objects = cp.objects;
  const CollisionWorld world = CollisionWorld::build(cp.rest, WorldConfig{});
  const SupportPlane support = support_under(objects, Eigen::Vector3d::UnitZ());
  const UntouchedDrift drift = untouched_drift(objects, support, DynamicsParams{});
  const std::shared_ptr<const WholeSceneWorld> whole = whole_scene_world(world, objects, drift);
  EXPECT_GT(drift.moved[0], 1e-4);  // it did settle, and it stands where it settled in the whole scene
  EXPECT_LT((whole->poses[0].position - drift.settled[0].position).norm(), 1e-12);
  GaussianScene both = cp.rest;
  const GaussianScene moved = placed(cp.half, objects[0].rest_origin, drift.settled[0]);
  for (std::size_t i = 0; i < moved.size(); ++i) both.push_back_from(moved, i);
  const CollisionWorld standing = CollisionWorld::build(both, WorldConfig{});
  const double R = 0.005;
  double worst = 0, worst_alone = 0;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> across(-R, R), along(-0.1, 0.1);
  for (int site = 0; site < 16; ++site) {
    const Eigen::Vector2d xy(across(rng), along(rng));
    WholeSceneOptions with, alone;
    with.world = whole;
    alone.enabled = false;
    const auto felt = make_object_renderer(RendererSpec{}, world, objects, std::make_shared<ObjectDynamics>(objects, support), {}, with);
    const auto halves = make_object_renderer(RendererSpec{}, world, objects, std::make_shared<ObjectDynamics>(objects, support), {}, alone);
    const auto one = make_force_renderer(RendererSpec{}, standing);
    Eigen::Vector3d f, f_alone, f_one;
    for (int k = 0; k <= 600; ++k) {  // 0.3 s 1 cm above (the side settles), 2 mm in over 0.25 s, held
      const double z = R + 0.01 - 0.012 * std::clamp((k - 300) / 250.0, 0.0, 1.0);
      const ToolEllipsoid tool = ToolEllipsoid::sphere(Eigen::Vector3d(xy.x(), xy.y(), z), R);
      const Eigen::Vector3d v(0, 0, k > 300 && k < 550 ? -0.048 : 0);
      f = felt->render(tool, v, 1e-3).force;
      f_alone = halves->render(tool, v, 1e-3).force;
      f_one = one->render(tool, v, 1e-3).force;
    }
    SCOPED_TRACE(testing::Message() << "site " << xy.transpose());
    ASSERT_GT(f_one.norm(), 1.0);
    EXPECT_GT(felt->whole_scene_weight(), 0.99);
    worst = std::max(worst, (f - f_one).norm() / f_one.norm());
    worst_alone = std::max(worst_alone, (f_alone - f_one).norm() / f_one.norm());
  }
  EXPECT_LT(worst, 0.01);
  EXPECT_GT(worst_alone, 0.03);
  RecordProperty("worst_relative_error", std::to_string(worst));
  RecordProperty("worst_relative_error_per_body_proxies", std::to_string(worst_alone));
}

// An object that does not stand on its support as cut is told apart before a run: a box resting
// on the plane stays (under 1 mm, 1 degree in 1 s); the same box 5 cm over it falls those 5 cm
// (within 5 mm); a tall thin box stood on one edge tips over.
TEST(ObjectDynamics, AnObjectThatDoesNotStandOnItsSupportIsToldApart) {
  const RigidObject box = box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.5);
  SupportPlane low = support_under(std::vector<RigidObject>{box}, Eigen::Vector3d::UnitZ());
  const UntouchedDrift resting = untouched_drift(std::vector<RigidObject>{box}, low, DynamicsParams{});
  EXPECT_LT(resting.moved[0], 1e-3);
  EXPECT_LT(resting.turned[0], M_PI / 180);
  low.point.z() -= 0.05;
  const UntouchedDrift falling = untouched_drift(std::vector<RigidObject>{box}, low, DynamicsParams{});
  EXPECT_NEAR(falling.moved[0], 0.05, 5e-3);
  ObjectSpec spec;
  spec.text = "slab on its edge";
  const RigidObject slab = make_rigid_object(
      box_surface_gaussians(Eigen::Vector3d(0, 0, 0.1), Eigen::Vector3d(0.005, 0.05, 0.1), 0.01), spec, WorldConfig{});
  const std::vector<RigidObject> tall{slab};
  // Its hull turned 10 degrees about y (the dynamics' geometry only): it stands on one bottom
  // edge, its centre of mass past it.
  std::vector<RigidObject> leaning = tall;
  const Eigen::Quaterniond q(Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitY()));
  for (Eigen::Vector3d& p : leaning[0].hull_points) p = q * p;
  const UntouchedDrift tipping = untouched_drift(leaning, support_under(leaning, Eigen::Vector3d::UnitZ()), DynamicsParams{});
  EXPECT_GT(tipping.turned[0], kUntouchedTurnWarn);
}

// A cut seated on its ground (seat_on_support): the box 2 cm over the plane reaches down to it,
// and one whose hull pokes 1 cm into it is raised onto it (as cut, either moves); either then
// stays within 1 mm and 1 degree in its first second, its lowest hull point on the plane. Only
// the bottom pieces of an object of several reach down, each keeping its own points. A box twice
// its height over the plane, or 0.5 mm under it, is left as it is.
TEST(ObjectDynamics, ACutSeatedOnItsGroundStandsStill) {
  const RigidObject box = box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.5);
  const SupportPlane at = support_under(std::vector<RigidObject>{box}, Eigen::Vector3d::UnitZ());
  const auto lowest = [&](const RigidObject& o, const SupportPlane& p) {
    double h = 1e9;
    for (const Eigen::Vector3d& q : o.hull_points) h = std::min(h, p.normal.dot(o.rest_origin + q - p.point));
    return h;
  };
  for (const double offset : {-0.02, 0.01}) {  // the plane 2 cm under the box, then 1 cm into it
    SupportPlane plane = at;
    plane.point.z() += offset;
    const UntouchedDrift before = untouched_drift(std::vector<RigidObject>{box}, plane, DynamicsParams{});
    EXPECT_GT(before.moved[0], 2e-3) << offset;  // as cut it does not stand
    RigidObject seated = box;
    EXPECT_NEAR(seat_on_support(seated, plane), -offset, 1e-9) << offset;
    EXPECT_NEAR(lowest(seated, plane), 0.0, 1e-9) << offset;
    EXPECT_EQ(seated.piece_ends.back(), seated.hull_points.size());
    const UntouchedDrift after = untouched_drift(std::vector<RigidObject>{seated}, plane, DynamicsParams{});
    EXPECT_LT(after.moved[0], 1e-3) << offset;
    EXPECT_LT(after.turned[0], M_PI / 180) << offset;
  }
  for (const double offset : {-0.12, 0.0005}) {  // 2 heights under it; 0.5 mm into it
    SupportPlane plane = at;
    plane.point.z() += offset;
    RigidObject left = box;
    EXPECT_EQ(seat_on_support(left, plane), 0.0) << offset;
    EXPECT_EQ(left.hull_points, box.hull_points) << offset;
  }
  // An arch of three pieces 2 cm over the plane: its two legs reach down, its top does not.
  GaussianScene arch = box_surface_gaussians(Eigen::Vector3d(-0.06, 0, 0.04), Eigen::Vector3d(0.02, 0.02, 0.04), 0.005);
  const GaussianScene right = box_surface_gaussians(Eigen::Vector3d(0.06, 0, 0.04), Eigen::Vector3d(0.02, 0.02, 0.04), 0.005);
  const GaussianScene top = box_surface_gaussians(Eigen::Vector3d(0, 0, 0.1), Eigen::Vector3d(0.08, 0.02, 0.02), 0.005);
  for (const GaussianScene* g : {&right, &top})
    for (std::size_t i = 0; i < g->size(); ++i) arch.push_back_from(*g, i);
  ObjectSpec spec;
  spec.hulls = 3;
  spec.text = "arch";
  const RigidObject cut = make_rigid_object(arch, spec, WorldConfig{});
  ASSERT_EQ(cut.piece_ends.size(), 3u);
  SupportPlane under = support_under(std::vector<RigidObject>{cut}, Eigen::Vector3d::UnitZ());
  under.point.z() -= 0.02;
  RigidObject seated = cut;
  EXPECT_NEAR(seat_on_support(seated, under), 0.02, 1e-9);
  int grown = 0;
  for (std::size_t k = 0; k < 3; ++k) {
    const std::span<const Eigen::Vector3d> was = cut.piece(k), now = seated.piece(k);
    double piece_lowest = 1e9;
    for (const Eigen::Vector3d& q : was) piece_lowest = std::min(piece_lowest, cut.rest_origin.z() + q.z() - under.point.z());
    ASSERT_GE(now.size(), was.size());
    EXPECT_TRUE(std::equal(was.begin(), was.end(), now.begin())) << k;  // its own points first, unchanged
    const bool leg = piece_lowest < 0.021;
    EXPECT_EQ(now.size(), leg ? 2 * was.size() : was.size()) << k;
    grown += leg;
  }
  EXPECT_EQ(grown, 2);
}

// object_support seats cuts, never a file object (placed by its own registration) nor an object
// when static supports are named (it stands on them).
TEST(ObjectDynamics, ObjectSupportSeatsCutsOnly) {
  // In the world's frame up is -y (CollisionWorld::up with no --up): a floor slab whose top is y = -0.5 mm.
  const CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0.0105, 0), Eigen::Vector3d(0.3, 0.01, 0.3), 0.01), WorldConfig{});
  ObjectSpec spec;
  spec.text = "hovering box";
  // A box of discs 5 mm over the floor's top.
  const GaussianScene g = box_surface_gaussians(Eigen::Vector3d(0, -0.035, 0), Eigen::Vector3d(0.05, 0.03, 0.04), 0.01);
  for (const ObjectSpec::Cut cut : {ObjectSpec::Cut::kBox, ObjectSpec::Cut::kIndices, ObjectSpec::Cut::kFile}) {
    spec.cut = cut;
    std::vector<RigidObject> objects{make_rigid_object(g, spec, WorldConfig{})};
    const std::size_t points = objects[0].hull_points.size();
    const ObjectSupport held = object_support(floor, objects, {});
    ASSERT_TRUE(held.fit.fitted);
    if (cut == ObjectSpec::Cut::kFile) {
      EXPECT_EQ(held.base[0], 0.0);
      EXPECT_EQ(objects[0].hull_points.size(), points);
    } else {
      EXPECT_NEAR(held.base[0], 0.005, 0.002);
      EXPECT_GT(objects[0].hull_points.size(), points);
    }
  }
  spec.cut = ObjectSpec::Cut::kBox;
  std::vector<RigidObject> objects{make_rigid_object(g, spec, WorldConfig{})};
  const std::vector<RigidObject> table{make_rigid_object(
      box_surface_gaussians(Eigen::Vector3d(0, 0.01, 0), Eigen::Vector3d(0.1, 0.01, 0.1), 0.01), spec, WorldConfig{})};
  const ObjectSupport on_table = object_support(floor, objects, table);
  EXPECT_EQ(on_table.base[0], 0.0);
  EXPECT_EQ(on_table.plane.hulls.size(), 1u);
}

// A convex object stays one piece whatever it is allowed: every face's plane has the whole box
// on one side.
TEST(ObjectDynamics, ABoxAskedForPiecesStaysOne) {
  ObjectSpec spec;
  spec.hulls = 4;
  spec.text = "box";
  const RigidObject box = make_rigid_object(
      box_surface_gaussians(Eigen::Vector3d(0, 0, 0.03), Eigen::Vector3d(0.05, 0.04, 0.03), 0.005), spec, WorldConfig{});
  EXPECT_EQ(box.piece_ends.size(), 1u);
  EXPECT_EQ(box.piece_ends.back(), box.hull_points.size());
  // Degenerate input: nothing to cut, or no scale to cut at.
  EXPECT_TRUE(split_into_pieces({}, {}, 1e-3, 3).empty());
  const std::vector<Eigen::Vector3d> two{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX()}, up(2, Eigen::Vector3d::UnitZ());
  EXPECT_EQ(split_into_pieces(two, up, 0.0, 3), (std::vector<int>{0, 0}));
}

TEST(ObjectSpec, HullsAreParsedAndBounded) {
  EXPECT_EQ(parse_object_spec("box:0,0,0,1,1,1:hulls=4").hulls, 4);
  EXPECT_EQ(parse_object_spec("box:0,0,0,1,1,1").hulls, 1);
  for (const char* bad : {"box:0,0,0,1,1,1:hulls=0", "box:0,0,0,1,1,1:hulls=2.5", "box:0,0,0,1,1,1:hulls=17"})
    EXPECT_THROW((void)parse_object_spec(bad), InputError) << bad;
  const ObjectSpecList list = parse_object_specs_json(R"({"objects": [{"box": [0, 0, 0, 1, 1, 1], "hulls": 3}]})", "t.json", ".");
  EXPECT_EQ(list.objects.at(0).hulls, 3);
  EXPECT_THROW((void)parse_object_specs_json(R"({"objects": [{"box": [0, 0, 0, 1, 1, 1], "hulls": 0}]})", "t.json", "."),
               InputError);
}

// The ground is fitted to the static scene around the objects: a floor tilted 6 degrees, 2 cm
// under a box, is found (tilt within 0.5 degree, height within 1 mm), and the box drops onto
// it; a scene with nothing around the objects falls back on the plane under them.
TEST(ObjectDynamics, TheSupportIsTheGroundFittedAroundTheObjects) {
  const Eigen::Vector3d half(0.05, 0.04, 0.03);
  const std::vector<RigidObject> objects{box_object(half, 0.4, 0.5)};  // bottom at z = 0
  const double tilt = 6 * M_PI / 180;
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitY()));
  SimilarityTransform T;
  T.rotation = turn;
  T.translation = Eigen::Vector3d(0, 0, -0.02);
  WorldConfig cfg;
  cfg.registration = T;  // a floor slab whose top is z = 0, then turned and lowered 2 cm
  const CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.01), Eigen::Vector3d(0.3, 0.3, 0.01), 0.01), cfg);
  const SupportFit fit = fit_support_plane(floor, objects, Eigen::Vector3d::UnitZ());
  ASSERT_TRUE(fit.fitted);
  EXPECT_GT(fit.points, 100u);
  EXPECT_NEAR(fit.tilt, tilt, 0.5 * M_PI / 180);
  EXPECT_LT(fit.rms, 1e-3);
  const Eigen::Vector3d n = turn * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(fit.plane.normal.dot(n), 1.0, 1e-4);
  EXPECT_NEAR(n.dot(fit.plane.point - T.translation), 0.0, 1e-3);  // on the floor's top face
  // The box drops onto it and rests (mu 0.5 holds it on a 6 degree slope).
  ObjectDynamics d(objects, fit.plane);
  for (int k = 0; k < 1000; ++k) d.step();
  const double gap = n.dot(d.center_of_mass(0) - fit.plane.point);
  EXPECT_NEAR(gap, half.z(), 3e-3) << "the box's centre is not half its height over the fitted ground";
  // Nothing around the objects: the plane under them.
  const CollisionWorld far = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(2, 2, -1), Eigen::Vector3d(0.1, 0.1, 0.01), 0.01), WorldConfig{});
  const SupportFit none = fit_support_plane(far, objects, Eigen::Vector3d::UnitZ());
  EXPECT_FALSE(none.fitted);
  EXPECT_NEAR(none.plane.point.z(), support_under(objects, Eigen::Vector3d::UnitZ()).point.z(), 1e-12);
}

// The objects JSON (--objects): the three kinds, mass and friction, paths relative to the JSON's
// folder, an inline registration; each error names the file and the entry.
TEST(ObjectSpec, AnObjectsJsonGivesTheSameSpecs) {
  const ObjectSpecList list = parse_object_specs_json(
      R"({"objects": [{"box": [1, 0, 0, 0, 1, 1], "mass": 0.3},
                      {"indices": [5, 3, 5], "friction": 0.2},
                      {"file": "cup.ply", "registration": {"translation": [0, 0, 1]}},
                      {"file": "/abs/mug.ply", "registration": "mug.json"}],
          "supports": [{"box": [-1, -1, -1, 1, 1, 0]}]})",
      "scene.json", "/data/scenes");
  const std::vector<ObjectSpec>& specs = list.objects;
  ASSERT_EQ(list.supports.size(), 1u);
  EXPECT_EQ(list.supports[0].box_hi, Eigen::Vector3d(1, 1, 0));
  ASSERT_EQ(specs.size(), 4u);
  EXPECT_EQ(specs[0].cut, ObjectSpec::Cut::kBox);
  EXPECT_EQ(specs[0].box_lo, Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(specs[0].box_hi, Eigen::Vector3d(1, 1, 1));
  EXPECT_EQ(specs[0].mass, 0.3);
  EXPECT_EQ(specs[0].friction, kDefaultObjectFriction);
  EXPECT_EQ(specs[1].indices, (std::vector<std::uint32_t>{3, 5}));
  EXPECT_EQ(specs[1].friction, 0.2);
  EXPECT_EQ(specs[2].file, "/data/scenes/cup.ply");
  ASSERT_TRUE(specs[2].registration.has_value());
  EXPECT_EQ(specs[2].registration->translation, Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(specs[3].file, "/abs/mug.ply");
  EXPECT_EQ(specs[3].registration_file, "/data/scenes/mug.json");
  const auto error = [](const std::string& text) {
    try {
      (void)parse_object_specs_json(text, "scene.json", "");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error(R"({"objects": [{"box": [0, 0, 0, 1, 1]}]})").find("scene.json: objects[0]"), std::string::npos);
  EXPECT_NE(error(R"({"objects": [{}, {"box": [0, 0, 0, 1, 1, 1], "file": "a.ply"}]})").find("objects[0]"), std::string::npos);
  EXPECT_NE(error(R"({"objects": [{"indices": [1]}, {"indices": [-1]}]})").find("objects[1]"), std::string::npos);
  EXPECT_NE(error(R"({"objects": [{"indices": [1], "mass": 0}]})").find("mass"), std::string::npos);
  EXPECT_NE(error(R"({"objects": [{"indices": [1], "registration": "r.json"}]})").find("file objects"), std::string::npos);
  EXPECT_NE(error("{not json").find("not valid JSON"), std::string::npos);
  EXPECT_NE(error(R"({"things": []})").find("expected"), std::string::npos);
  EXPECT_NE(error(R"({"objects": [], "supports": [{"file": "t.ply"}]})").find("supports[0]: a support is a part"),
            std::string::npos);
  EXPECT_THROW((void)load_object_specs(testing::TempDir() + "/no_such_objects.json"), InputError);
}

// A track full of rows drops and counts the rest rather than allocating.
TEST(ObjectTrack, DropsPastItsCapacity) {
  ObjectTrack track(2, 3);
  ObjectPoses p;
  p.count = 2;
  for (int k = 0; k < 5; ++k) {
    p.time = k;
    p.poses[1].position = Eigen::Vector3d(k, 0, 0);
    track.push(p);
  }
  EXPECT_EQ(track.rows(), 3u);
  EXPECT_EQ(track.dropped(), 2u);
  EXPECT_EQ(track.position(2, 1).x(), 2.0);
  EXPECT_EQ(track.time(2), 2.0);
}

// `synth box-on-floor`'s scene: its --object text cuts every Gaussian of the box and none of the
// floor, and the box's colour goes with it into the world frame.
TEST(SceneCut, TheBoxOnFloorSpecCutsTheBoxWithItsColour) {
  const BoxOnFloor b = box_on_floor(Eigen::Vector3d(0.05, 0.04, 0.03), Eigen::Vector2d(0.2, 0.2), 0.01);
  const std::size_t box_count = box_surface_gaussians(Eigen::Vector3d(0, 0, 0.03), Eigen::Vector3d(0.05, 0.04, 0.03), 0.01).size();
  ASSERT_EQ(b.scene.colors_dc.size(), b.scene.size());
  const ObjectSpec spec = parse_object_spec(b.object_spec);
  SimilarityTransform T;
  T.translation = Eigen::Vector3d(0, 0, 0);
  const SceneCut cut = cut_objects(b.scene, T, std::span<const ObjectSpec>(&spec, 1), 0.2f);
  ASSERT_EQ(cut.objects[0].size(), box_count);
  for (std::size_t k = 0; k < box_count; ++k) EXPECT_LT(cut.objects[0].source_index[k], box_count);
  ASSERT_EQ(cut.objects[0].colors_dc.size(), box_count);
  EXPECT_EQ(cut.objects[0].colors_dc[0], b.scene.colors_dc[0]);
  EXPECT_EQ(cut.rest.colors_dc.size(), cut.rest.size());
  EXPECT_THROW((void)box_on_floor(Eigen::Vector3d(0.05, 0, 0.03), Eigen::Vector2d(0.2, 0.2), 0.01), InputError);
}

TEST(ObjectDynamics, ATallBoxPushedHighTipsAtTheAnalyticForce) {
  const double mu = 1.0, mass = 0.3;
  const RigidObject box = box_object(Eigen::Vector3d(0.03, 0.04, 0.10), mass, mu);
  const std::vector<RigidObject> objects{box};
  const SupportPlane plane = support_under(objects, Eigen::Vector3d::UnitZ());
  // The pivot: the edge of the hull's face on the plane, on the far side of the push (+x); the
  // push acts at height z_push on the near face, along +x. Torques about the pivot:
  // F z = m g (x_pivot - x_com). The face on the plane is spanned by the bottom discs' thin-axis
  // tips, so it ends half a disc short of the box's edge, and the box first tips about that.
  double x_pivot = -1e9;
  for (const Eigen::Vector3d& p : box.hull_points)
    if (box.rest_origin.z() + p.z() < plane.point.z() + 1e-6) x_pivot = std::max(x_pivot, box.rest_origin.x() + p.x());
  const double z_push = plane.point.z() + 0.17;
  ObjectDynamics probe(objects, plane);
  const Eigen::Vector3d com = probe.center_of_mass(0);
  const double F_tip = mass * kG * (x_pivot - com.x()) / (z_push - plane.point.z());
  ASSERT_LT(F_tip, mu * mass * kG);  // it tips before it slides
  for (const double ratio : {0.95, 1.05}) {
    ObjectDynamics d(objects, plane);
    for (int k = 0; k < 300; ++k) d.step();
    double tilt = 0;
    for (int k = 0; k < 600; ++k) {
      const BodyPose& p = d.pose(0);
      const Eigen::Vector3d at = p.position + p.rotation * (Eigen::Vector3d(-0.03, 0, z_push) - box.rest_origin);
      d.apply_wrench(0, Eigen::Vector3d(ratio * F_tip, 0, 0), at);
      d.step();
      tilt = std::max(tilt, Eigen::AngleAxisd(d.pose(0).rotation).angle());
    }
    SCOPED_TRACE(testing::Message() << "F/F_tip " << ratio << " F_tip " << F_tip << " N");
    if (ratio < 1) {
      EXPECT_LT(tilt, 0.02);
    } else {
      EXPECT_GT(tilt, 0.1);
    }
  }
}

// The wrench an ObjectRenderer gives for an object at rest (pressed lightly from above, it stays
// put) equals a ProxyRenderer's on a static world of the same Gaussians: the body frame, the
// velocities and the torque are carried back correctly, for a sphere and a tilted stylus and disc
// (the disc touches with its rim: a torque about the TCP).
TEST(ObjectRenderer, AnObjectAtRestIsFeltAsTheSameGaussiansHeldStill) {
  ObjectSpec spec;
  spec.mass = 50;  // a light press never moves it
  spec.friction = 1;
  spec.text = "heavy box";
  const Eigen::Vector3d half(0.05, 0.04, 0.03);
  const GaussianScene gaussians = box_surface_gaussians(Eigen::Vector3d(0.02, -0.01, half.z()), half, 0.01);
  const std::vector<RigidObject> objects{make_rigid_object(gaussians, spec, WorldConfig{})};
  // The floor is far below the tool: only the box is touched.
  const CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.2), Eigen::Vector3d(0.3, 0.3, 0.01), 0.02), WorldConfig{});
  for (const char* tool_spec : {"sphere:0.008", "stylus:0.06,0.004", "disc:0.012,0.002"}) {
    SCOPED_TRACE(tool_spec);
    const CompoundTool tool = parse_tool_spec(tool_spec);
    auto dynamics = std::make_shared<ObjectDynamics>(objects, support_under(objects, Eigen::Vector3d::UnitZ()));
    for (int k = 0; k < 500; ++k) dynamics->step();  // settled into the soft contact (it sinks a little)
    // The reference: the same Gaussians held still where the object rests now.
    const BodyPose rest = dynamics->pose(0);
    WorldConfig where;
    where.registration.rotation = rest.rotation;
    where.registration.translation = rest.position - rest.rotation * objects[0].rest_origin;
    const CollisionWorld still = CollisionWorld::build(gaussians, where);
    // The per-body proxies alone: the whole scene's proxy reads the box where it was captured, not
    // where it settled.
    WholeSceneOptions alone;
    alone.enabled = false;
    const auto moving = make_object_renderer(RendererSpec{}, floor, objects, dynamics, {}, alone);
    const auto reference = make_force_renderer(RendererSpec{}, still);
    moving->set_tool(tool);
    reference->set_tool(tool);
    const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized()));
    std::array<ToolEllipsoid, kMaxToolParts> parts;
    double peak = 0, peak_torque = 0, worst_force = 0, worst_torque = 0;
    // The TCP's height above the tool's lowest point, as posed.
    const int m = tool.posed(Eigen::Vector3d::Zero(), tilt, parts);
    double lowest = 0;
    for (int j = 0; j < m; ++j) lowest = std::min(lowest, parts[j].center.z() - parts[j].aabb_half_extent().z());
    const double top = rest.position.z() + half.z();
    for (int k = 0; k < 600; ++k) {  // down onto the top face, 4 mm in, then held
      const double depth = std::min(k * 2e-5 - 0.002, 0.004);
      const Eigen::Vector3d tcp(0.03, 0.0, top - lowest - depth);
      const Eigen::Vector3d v(0, 0, k * 2e-5 < 0.006 ? -0.02 : 0);
      const int n = tool.posed(tcp, tilt, parts);
      const std::span<const ToolEllipsoid> posed(parts.data(), std::size_t(n));
      const RenderOutput a = moving->render_compound(posed, tcp, v, Eigen::Vector3d::Zero(), 1e-3);
      const RenderOutput b = reference->render_compound(posed, tcp, v, Eigen::Vector3d::Zero(), 1e-3);
      peak = std::max(peak, b.force.norm());
      peak_torque = std::max(peak_torque, b.torque.norm());
      worst_force = std::max(worst_force, (a.force - b.force).norm());
      worst_torque = std::max(worst_torque, (a.torque - b.torque).norm());
    }
    EXPECT_GT(peak, 1.0);  // it was pressed
    EXPECT_LT((dynamics->pose(0).position - rest.position).norm(), 1e-4);  // and stayed put
    EXPECT_LT(worst_force, 0.02 * peak);
    EXPECT_LT(worst_torque, 0.02 * peak * tool.reach());
    RecordProperty(std::string(tool_spec).substr(0, std::string(tool_spec).find(':')) + "_worst_force_over_peak", std::to_string(worst_force / peak));
    RecordProperty(std::string(tool_spec).substr(0, std::string(tool_spec).find(':')) + "_torque_worst_and_peak",
                   std::to_string(worst_torque) + " " + std::to_string(peak_torque));
  }
}

// Where the box stood, the capture has a hole; once the box is pushed away, the hand lowered
// there meets the support plane (spring k_c), and nowhere else: not beside the footprint, and
// not a hand that starts deep under the plane (it never reached it from above).
TEST(ObjectRenderer, TheSupportPlaneCarriesTheHandWhereTheCutLeftAHole) {
  const std::vector<RigidObject> objects{box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.3)};
  const CollisionWorld far = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.3), Eigen::Vector3d(0.3, 0.3, 0.01), 0.02), WorldConfig{});
  auto dynamics = std::make_shared<ObjectDynamics>(objects, support_under(objects, Eigen::Vector3d::UnitZ()));
  const auto renderer = make_object_renderer(RendererSpec{}, far, objects, dynamics);
  const double r = 0.008, plane = dynamics->support().point.z(), k = ProxyParams{}.stiffness;
  const Eigen::Vector3d away(0.5, 0, plane + 0.2);  // the hand far from everything
  // Push the box 15 cm along +y, out of its footprint.
  for (int t = 0; t < 1500 && dynamics->pose(0).position.y() < 0.15; ++t) {
    dynamics->apply_wrench(0, Eigen::Vector3d(0, 4 * 0.3 * 0.4 * kG, 0), dynamics->center_of_mass(0));
    (void)renderer->render(ToolEllipsoid::sphere(away, r), Eigen::Vector3d::Zero(), 1e-3);
  }
  ASSERT_GT(dynamics->pose(0).position.y(), 0.15);
  RenderOutput out;
  for (int t = 0; t < 400; ++t) {  // down where the box stood to 3 mm past the plane, then held
    const double z = std::max(plane + r - 0.003, plane + r + 0.01 - t * 5e-5);
    out = renderer->render(ToolEllipsoid::sphere(Eigen::Vector3d(0.02, 0, z), r), Eigen::Vector3d::Zero(), 1e-3);
  }
  EXPECT_NEAR(out.force.z(), k * 0.003, 0.01 * k * 0.003);
  EXPECT_LT(out.force.head<2>().norm(), 1e-9);
  // Above the plane nothing pushes.
  out = renderer->render(ToolEllipsoid::sphere(Eigen::Vector3d(0.02, 0, plane + r + 0.001), r), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(out.force.norm(), 0.0);
  // Beside the footprint, 3 mm under the plane: the scene (here: none) holds the hand, not the plane.
  for (int t = 0; t < 10; ++t)
    out = renderer->render(ToolEllipsoid::sphere(Eigen::Vector3d(0.15, -0.1, plane + r - 0.003), r), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(out.force.norm(), 0.0);
  // A hand that arrives deep under the plane (from beside it, under the scene) is not shoved up.
  for (int t = 0; t < 10; ++t)
    out = renderer->render(ToolEllipsoid::sphere(Eigen::Vector3d(0.02, 0, plane - 0.05), r), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(out.force.norm(), 0.0);
}

// MuJoCo's heap, counted (mju_user_malloc), for the tick's no-allocation test.
std::atomic<long> mujoco_mallocs{0};
void* counting_malloc(std::size_t size) {
  mujoco_mallocs.fetch_add(1);
  return std::aligned_alloc(64, (size + 63) / 64 * 64);  // MuJoCo's own allocator aligns to 64 bytes
}

// The servo tick does not allocate: pushing a box (proxy sweeps, the reaction, MuJoCo steps with
// contacts, waking from sleep) calls neither operator new nor MuJoCo's allocator.
TEST(ObjectRenderer, ATickPushingABoxDoesNotAllocate) {
  const std::vector<RigidObject> objects{box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.3)};
  const CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.0105), Eigen::Vector3d(0.4, 0.3, 0.01), 0.01), WorldConfig{});
  auto dynamics = std::make_shared<ObjectDynamics>(objects, support_under(objects, Eigen::Vector3d::UnitZ()));
  const auto renderer = make_object_renderer(RendererSpec{}, floor, objects, dynamics);
  mju_user_malloc = counting_malloc;
  mju_user_free = std::free;
  const std::size_t before = test::allocation_count();
  const long mujoco_before = mujoco_mallocs.load();
  double moved = 0;
  for (int k = 0; k < 3000; ++k) {  // rest (it sleeps), then the tool walks into the box and pushes it
    const double x = std::min(-0.12 + std::max(0, k - 500) * 1e-4, 0.1);
    const RenderOutput out = renderer->render(ToolEllipsoid::sphere(Eigen::Vector3d(x, 0, 0.03), 0.01),
                                              Eigen::Vector3d(0.1, 0, 0), 1e-3);
    moved = std::max(moved, out.force.norm());
  }
  const std::size_t allocations = test::allocation_count() - before;
  const long mujoco = mujoco_mallocs.load() - mujoco_before;
  {  // the counter does see MuJoCo's allocations: a model and its data
    const ObjectDynamics another(objects, dynamics->support());
    EXPECT_GT(mujoco_mallocs.load() - mujoco_before, mujoco);
  }
  mju_user_malloc = nullptr;
  mju_user_free = nullptr;
  EXPECT_GT(moved, 1.0);
  EXPECT_GT(dynamics->pose(0).position.x(), objects[0].rest_origin.x() + 0.02);  // it was pushed
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(mujoco, 0);
}

// A box the hand pushes away leaves the whole scene: the whole scene's weight falls from 1 (the
// box standing) to 0 (it slid off) within the first rest tolerance of its slide, and the hand's
// force moves tick to tick as smoothly as with the per-body proxies alone (the blend adds no step
// over 0.05 N), and afterwards is theirs. Away from the box, the whole scene's proxy starts again.
TEST(ObjectRenderer, ABoxPushedAwayLeavesTheWholeSceneWithoutAJump) {
  const std::vector<RigidObject> objects{box_object(Eigen::Vector3d(0.05, 0.04, 0.03), 0.4, 0.3)};
  const CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.0105), Eigen::Vector3d(0.4, 0.3, 0.01), 0.01), WorldConfig{});
  const SupportPlane support = support_under(objects, Eigen::Vector3d::UnitZ());
  WholeSceneOptions alone;
  alone.enabled = false;
  const auto dyn_with = std::make_shared<ObjectDynamics>(objects, support);
  const auto dyn_alone = std::make_shared<ObjectDynamics>(objects, support);
  const auto with = make_object_renderer(RendererSpec{}, floor, objects, dyn_with);
  const auto halves = make_object_renderer(RendererSpec{}, floor, objects, dyn_alone, {}, alone);
  Eigen::Vector3d last_with = Eigen::Vector3d::Zero(), last_alone = Eigen::Vector3d::Zero();
  double step_with = 0, step_alone = 0, first_weight = -1, last_weight = -1, weight_at_tolerance = 1;
  for (int k = 0; k < 2500; ++k) {  // rest, then the tool walks into the box and pushes it 8 cm
    const double x = std::min(-0.12 + std::max(0, k - 500) * 1e-4, 0.0);
    const ToolEllipsoid tool = ToolEllipsoid::sphere(Eigen::Vector3d(x, 0, 0.03), 0.01);
    const Eigen::Vector3d a = with->render(tool, Eigen::Vector3d(0.1, 0, 0), 1e-3).force;
    const Eigen::Vector3d b = halves->render(tool, Eigen::Vector3d(0.1, 0, 0), 1e-3).force;
    if (k > 0) {
      step_with = std::max(step_with, (a - last_with).norm());
      step_alone = std::max(step_alone, (b - last_alone).norm());
    }
    last_with = a;
    last_alone = b;
    const double slid = (dyn_with->pose(0).position - objects[0].rest_origin).norm();
    if (a.norm() > 0.1 && first_weight < 0) first_weight = with->whole_scene_weight();
    if (slid > 2 * kWholeSceneRestTolerance && weight_at_tolerance == 1) weight_at_tolerance = with->whole_scene_weight();
    last_weight = with->whole_scene_weight();
  }
  EXPECT_GT(dyn_with->pose(0).position.x() - objects[0].rest_origin.x(), 0.02);  // it was pushed
  EXPECT_NEAR(first_weight, 1.0, 1e-3);     // first touched standing: the whole scene
  EXPECT_LT(weight_at_tolerance, 1e-12);    // gone once the box slid past the tolerance
  EXPECT_EQ(last_weight, 0.0);
  EXPECT_LT(step_with, step_alone + 0.05);
  EXPECT_LT((last_with - last_alone).norm(), 0.05 * last_alone.norm() + 1e-6);
  // Far from the box, the tool free, the whole scene's proxy starts again: pressing the floor
  // there, the hand gets its force (weight 1), the floor as the static scene's proxy has it.
  for (int k = 0; k < 1500; ++k) {  // back and away to x = -0.3 m over 0.6 s, then 2 mm into the floor
    const double x = std::max(0.0 - k * 5e-4, -0.3);
    const double z = k < 700 ? 0.03 : std::max(0.03 - (k - 700) * 1e-4, 0.01 - 0.002);
    const ToolEllipsoid tool = ToolEllipsoid::sphere(Eigen::Vector3d(x, 0, z), 0.01);
    last_with = with->render(tool, Eigen::Vector3d::Zero(), 1e-3).force;
    last_alone = halves->render(tool, Eigen::Vector3d::Zero(), 1e-3).force;
  }
  EXPECT_DOUBLE_EQ(with->whole_scene_weight(), 1.0);
  EXPECT_GT(last_alone.z(), 1.0);
  EXPECT_LT((last_with - last_alone).norm(), 0.01 * last_alone.norm());
  RecordProperty("largest_step_N_with_and_alone", std::to_string(step_with) + " " + std::to_string(step_alone));
}

// The push scenario on `surface`: a 0.4 kg box (mu 0.3) pushed by a 1 cm sphere from -x at
// mid-height through the servo step, held against Newton and Coulomb.
PushRun push_box_on(ProxySurface surface) {
  PushScenario scenario;
  ProxyModelSpec proxy;
  proxy.params.surface = surface;
  scenario.runtime.renderer = proxy;
  const PushRun run = run_push_scenario(scenario);
  EXPECT_EQ(run.samples.size(), std::size_t(run.runtime.ticks));
  EXPECT_GT(run.travelled, 0.08) << "the box was not pushed along";
  const PushSample& end = run.samples.back();
  EXPECT_LT(std::abs(end.box.y()), 0.01);
  EXPECT_LT(end.box_turn, 0.12) << "the box tipped or spun";  // (measured 0.093 on the ellipsoids, 0.101 seen)
  std::printf("%s: box turned %.4f rad, the tool at the proxy %.3f mm into the box, deepest K_min %.4f, friction "
              "%.3f of mu m g, lowest energy %.3g mJ\n",
              std::string(proxy_surface_name(surface)).c_str(), end.box_turn, run.deepest_box_depth * 1e3,
              run.deepest_k_min, run.friction_estimate / run.friction_expected, run.lowest_energy * 1e3);
  // The tool at its proxy never went into the box by more than the onset tolerance of issue 71's
  // check of the seen against the felt surface, 0.1 tool radii (1 mm): the seen solid's surface
  // is the discs' centre planes (a seen contact caught up with the sliding box begins up to
  // 0.53 mm in), the ellipsoids' lies outside them (0 mm).
  EXPECT_LT(run.deepest_box_depth, 0.1 * scenario.tool_radius);
  // While it slides, the push less m a is the friction (Newton, with Coulomb's mu m g).
  EXPECT_GT(run.sliding_ticks, 200);
  EXPECT_NEAR(run.friction_estimate, run.friction_expected, 0.05 * run.friction_expected);
  // The hand felt the box: the device stopped short of the hand's target while pushing.
  double lag = 0;
  for (const PushSample& s : run.samples) lag = std::max(lag, s.hand.x() - s.device.x());
  EXPECT_GT(lag, 0.001);
  // Pushing and letting go gave no energy back to the hand (the passivity observer at the
  // device's port, which sees what went into the box and what came back).
  EXPECT_GE(run.lowest_energy, -1e-6);
  EXPECT_GT(run.peak_energy, 1e-3);  // the push put energy into the box (friction took it)
  return run;
}

TEST(ObjectRenderer, TheSimulatedHandPushesABoxAcrossThePlaneThroughTheServoStep) {
  const PushRun run = push_box_on(ProxySurface::kEllipsoids);
  // The proxy never entered the box: no Gaussian of it overlaps the tool at the proxy by more
  // than a graze (K_min 1e-3 is a depth of about 0.05 % of the tool's radius).
  EXPECT_LT(run.deepest_k_min, 1e-3);
  RecordProperty("friction_over_mu_m_g", std::to_string(run.friction_estimate / run.friction_expected));
  RecordProperty("lowest_energy_J", std::to_string(run.lowest_energy));
}

TEST(ObjectRenderer, OnTheSeenSolidTheSimulatedHandPushesABoxAsOnTheEllipsoids) {
  (void)push_box_on(ProxySurface::kSeen);
}

}  // namespace
}  // namespace gshaptics
