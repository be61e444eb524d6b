// The simulated probe run on the bundled Truck, and the servo tick's allocation-free contract.

#include "gshaptics/sim/probe_run.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <cstdlib>
#include <fstream>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/error.h"
#include "gshaptics/servo/safety.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/seen_surface.h"
#include "gshaptics/session/probe_session.h"
#include "support/allocation_counter.h"
#include "support/ellipsoid_params.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

class TruckRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = &test::truck_world();
  }
  static const CollisionWorld* world_;
};
const CollisionWorld* TruckRun::world_ = nullptr;

TEST_F(TruckRun, ServoTickAllocatesNothing) {
  ContactQuery query(*world_);
  ForceModel force;
  // Warm up, then count allocations over ticks that sweep into the truck's dense middle.
  query.run(ToolEllipsoid::sphere(Eigen::Vector3d(0, 0, 0.5), 0.08));
  std::size_t max_contacts = 0;
  const std::size_t before = test::allocation_count();
  for (int k = 0; k < 400; ++k) {
    const Eigen::Vector3d p(0.0, 0.0, 1.6 - 0.004 * k);
    query.run(ToolEllipsoid::sphere(p, 0.08));
    const ForceOutput f = force.update(query.result().contacts(), p, Eigen::Vector3d(0, 0, -4), 1e-3);
    max_contacts = std::max<std::size_t>(max_contacts, f.contacts);
  }
  const std::size_t after = test::allocation_count();
  EXPECT_EQ(after - before, 0u);
  EXPECT_GT(max_contacts, 50u);  // the sweep really went through dense contact
}

TEST_F(TruckRun, SevenSitesEachTouchedWithForceAwayFromTheSurface) {
  ProbeParams pp;
  pp.tool_radius = 0.07;
  pp.approach_speed = 2 * pp.tool_radius;
  pp.travel_speed = 8 * pp.tool_radius;
  const ProbeTrajectory traj = generate_probe_trajectory(*world_, pp);
  ASSERT_EQ(traj.sites().size(), 7u);
  for (const auto& s : traj.sites()) {
    EXPECT_NEAR(s.normal.norm(), 1.0, 1e-9);
    EXPECT_GT(s.normal.z(), -0.2);  // reachable from above
  }
  const ProbeRunResult run = run_probe(*world_, traj, {});
  // Every tick of the trajectory and its 0.5 s rest, then the stop ramp (at most 0.1 s).
  const std::size_t planned = std::size_t(std::ceil((traj.duration() + 0.5) * 1000));
  ASSERT_GE(run.ticks.size(), planned);
  ASSERT_LE(run.ticks.size(), planned + 102);
  // Each site: within its press window the tool touches and the rendered force points out of
  // the surface (positive along the site's outward normal).
  for (const auto& s : traj.sites()) {
    std::uint32_t peak_contacts = 0;
    double peak_force = 0, along_normal = 0;
    for (const auto& t : run.ticks) {
      if (t.time < s.t_touch - 0.5 || t.time > s.t_touch + 1.5) continue;
      peak_contacts = std::max(peak_contacts, t.counts.contacts);
      if (t.force.norm() > peak_force) {
        peak_force = t.force.norm();
        along_normal = t.force.normalized().dot(s.normal);
      }
    }
    EXPECT_GT(peak_contacts, 0u) << "site " << s.gaussian_index;
    EXPECT_GT(peak_force, 0.5) << "site " << s.gaussian_index;
    EXPECT_GT(along_normal, 0.0) << "site " << s.gaussian_index;
  }
  EXPECT_GE(run.episodes.size(), 7u);
  // Without contact the renderer asks for no force (paper Sec. V-A b), and the force commanded
  // only falls (the safety layer's rate limit ramps it down within a tick or two).
  double prev = 0;
  for (const auto& t : run.ticks) {
    if (t.counts.contacts == 0) {
      ASSERT_EQ(t.desired.norm(), 0.0) << t.time;
      ASSERT_LE(t.force.norm(), prev + 1e-12) << t.time;
    }
    prev = t.force.norm();
  }
}

// The same run with a tool that has a shape (`simulate --tool`): a stylus held upright, tip at the
// TCP, through the same servo step. Every site is touched with the force out of the surface, and
// the simulated device, a force-only one, is sent no torque: the safety layer drops what the
// compound proxy asks for and flags those ticks.
TEST_F(TruckRun, AStylusTouchesEverySiteAndItsTorqueIsDroppedOnAForceOnlyDevice) {
  ProbeRunParams rp;
  rp.tool = parse_tool_spec("stylus:0.2,0.02");
  ProbeParams pp;
  pp.tool_radius = rp.tool.largest_semi_axis();  // as `simulate --tool` scales the trajectory
  pp.approach_speed = 2 * pp.tool_radius;
  pp.travel_speed = 8 * pp.tool_radius;
  pp.sites = 3;
  const ProbeTrajectory traj = generate_probe_trajectory(*world_, pp);
  const ProbeRunResult run = run_probe(*world_, traj, rp);
  for (const auto& s : traj.sites()) {
    double peak_force = 0, along_normal = 0;
    for (const auto& t : run.ticks) {
      if (t.time < s.t_touch - 0.5 || t.time > s.t_touch + 1.5) continue;
      if (t.force.norm() > peak_force) {
        peak_force = t.force.norm();
        along_normal = t.force.normalized().dot(s.normal);
      }
    }
    EXPECT_GT(peak_force, 0.5) << "site " << s.gaussian_index << " normal " << s.normal.transpose();
    EXPECT_GT(along_normal, 0.0) << "site " << s.gaussian_index;
  }
  std::size_t dropped = 0;
  for (const auto& t : run.ticks) {
    dropped += (t.flags & kFlagTorqueDropped) != 0;
    ASSERT_EQ(t.torque.norm(), 0.0) << t.time;  // never sent
  }
  EXPECT_GT(dropped, 100u);
  // A bad tool is an input error before any tick.
  rp.tool.count = 1;
  rp.tool.parts[0].semi_axes = Eigen::Vector3d(0.01, -1, 0.01);
  EXPECT_THROW((void)run_probe(*world_, traj, rp), InputError);
}

TEST_F(TruckRun, SameSeedSameTrajectoryOtherSeedOtherSites) {
  ProbeParams pp;
  pp.tool_radius = 0.07;
  const ProbeTrajectory a = generate_probe_trajectory(*world_, pp);
  const ProbeTrajectory b = generate_probe_trajectory(*world_, pp);
  pp.seed = 2;
  const ProbeTrajectory c = generate_probe_trajectory(*world_, pp);
  ASSERT_EQ(a.sites().size(), b.sites().size());
  for (std::size_t i = 0; i < a.sites().size(); ++i)
    EXPECT_EQ(a.sites()[i].gaussian_index, b.sites()[i].gaussian_index);
  EXPECT_NE(a.sites()[0].gaussian_index, c.sites()[0].gaussian_index);
}

// On the seen solid the probe run's touch points lie where the sphere's leading point meets the
// surface the splats render (the 3DGS median depth from the approach's start, an independent slow
// reference), not on the 1-sigma ellipsoids: on thick discs (sigma 8 x 8 x 3 mm) these stand
// 3 mm proud of the discs' plane, where a viewer sees the surface. A plateau 3 cm over a floor.
TEST(ProbeRun, OnTheSeenSurfaceTheTouchPointsAreWhereTheSurfaceIsSeen) {
  GaussianScene g;
  const double s = 0.008, top = 0.03;
  const auto layer = [&](double half, double z) {
    for (double x = -half; x <= half + 1e-12; x += s)
      for (double y = -half; y <= half + 1e-12; y += s)
        g.push_back(Eigen::Vector3f(float(x), float(y), float(z)), Eigen::Vector3f(0.008f, 0.008f, 0.003f),
                    Eigen::Vector4f(1, 0, 0, 0), 0.9f, std::uint32_t(g.size()));
  };
  layer(0.08, 0.0);
  layer(0.032, top);
  WorldConfig config;
  config.min_opacity = kSeenMinOpacity;
  const CollisionWorld world = CollisionWorld::build(g, config);
  const double r = 0.005;
  ProbeParams pp;
  pp.tool_radius = r;
  pp.sites = 3;
  const ProbeTrajectory on_ellipsoids = generate_probe_trajectory(world, pp);
  pp.first_touch = session::seen_first_touch(world, r);
  const ProbeTrajectory on_seen = generate_probe_trajectory(world, pp);
  ASSERT_EQ(on_seen.sites().size(), 3u);
  ASSERT_EQ(on_ellipsoids.sites().size(), 3u);
  const SeenSurface reference(g);
  for (std::size_t i = 0; i < 3; ++i) {
    const ProbeSite& site = on_seen.sites()[i];
    const Eigen::Vector3d start = site.surface_point + pp.approach_distance * r * site.normal;
    const SeenDepth seen = reference.median_depth(start, -site.normal);
    ASSERT_TRUE(seen.hit);
    const Eigen::Vector3d lead = site.touch_point - r * site.normal;
    EXPECT_NEAR((lead - (start - seen.depth * site.normal)).norm(), 0.0, 1e-3 * r) << "site " << i;
    EXPECT_NEAR(lead.z(), top, 1e-3 * r);  // the discs' plane, where their peaks composite
    // The same site on the ellipsoids is touched 3 mm higher (within the r / 8 steps).
    const ProbeSite& e = on_ellipsoids.sites()[i];
    ASSERT_EQ(e.gaussian_index, site.gaussian_index);
    EXPECT_NEAR(e.touch_point.z() - site.touch_point.z(), 0.003, r / 8);
  }
}

// A stylus held upright (the world's orientation) and pressed on a wall's side under a roof that
// overhangs the wall by 25 mm meets the roof with its body before its tip reaches the wall: the
// probe run leaves such sites out (ProbeParams::tool_touch), on the ellipsoids and on the seen
// solid, and keeps the ones its tip reaches first. A box of discs (x in [-40, 0] mm) under a roof
// 30 mm above its top, reaching from x = -30 mm to 25 mm past its +x face. (The probe's sphere
// is the stylus's largest semi-axis, 17 mm, 12 mm wider than the rod: a roof within that of the
// face is one the sphere's touch point already stands clear of.)
TEST(ProbeRun, AStylusIsNotSentToASiteItsBodyMeetsAnOverhangBefore) {
  GaussianScene g;
  const double s = 0.002, sigma = 0.002;
  const auto disc = [&](const Eigen::Vector3d& c, const Eigen::Vector3d& n) {
    const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n);
    g.push_back(c.cast<float>(), Eigen::Vector3f(float(sigma), float(sigma), 0.0005f),
                Eigen::Vector4f(float(q.w()), float(q.x()), float(q.y()), float(q.z())), 0.9f, std::uint32_t(g.size()));
  };
  for (double a = -0.04; a <= 1e-9; a += s)        // x across the box
    for (double b = -0.04; b <= 0.04 + 1e-9; b += s) {  // y
      disc({a, b, 0.06}, Eigen::Vector3d::UnitZ());       // the box's top
    }
  for (double b = -0.04; b <= 0.04 + 1e-9; b += s)
    for (double z = 0; z <= 0.06 + 1e-9; z += s) {
      disc({0, b, z}, Eigen::Vector3d::UnitX());          // the +x face, under the roof
      disc({-0.04, b, z}, -Eigen::Vector3d::UnitX());     // the -x face
    }
  for (double a = -0.04; a <= 1e-9; a += s)
    for (double z = 0; z <= 0.06 + 1e-9; z += s) {
      disc({a, 0.04, z}, Eigen::Vector3d::UnitY());
      disc({a, -0.04, z}, -Eigen::Vector3d::UnitY());
    }
  for (double a = -0.03; a <= 0.025 + 1e-9; a += s)
    for (double b = -0.03; b <= 0.03 + 1e-9; b += s) disc({a, b, 0.09}, Eigen::Vector3d::UnitZ());  // the roof
  WorldConfig config;
  config.min_opacity = kSeenMinOpacity;
  const CollisionWorld world = CollisionWorld::build(g, config);
  const double rod = 0.005;
  const CompoundTool stylus = parse_tool_spec("stylus:0.1,0.005");
  const double r = stylus.largest_semi_axis();
  // The tool's first touch along -x from 40 mm in front of the +x face, 30 mm up: the roof's
  // edge (25 mm out, its discs 2 mm wide) meets the rod's side 25-27 mm before the face would.
  const Eigen::Vector3d start(0.04, 0, 0.03);
  for (const bool seen : {false, true}) {
    const auto touch = session::tool_first_touch(world, stylus, seen);
    const double met = touch(start, -Eigen::Vector3d::UnitX(), 0.05);
    const double face = 0.04 - rod;  // the rod's side to the face's plane
    // (The ellipsoids at the outermost discs' 1-sigma rim; the seen solid a few mm in, where the
    // discs seen edge-on composite to half transmittance.)
    EXPECT_GE(met, face - 0.025 - sigma - 0.001) << (seen ? "seen" : "ellipsoids");
    EXPECT_LE(met, face - 0.02) << (seen ? "seen" : "ellipsoids");
    // (The parts are ellipsoids, narrower than the rod away from their middles; steps of 0.6 mm.)
    if (!seen) {
      EXPECT_NEAR(met, face - 0.025 - sigma, 0.002);
    }
    EXPECT_TRUE(std::isnan(touch(start, Eigen::Vector3d::UnitX(), 0.05))) << "moving away meets nothing";
  }
  ProbeParams pp;
  pp.tool_radius = r;
  pp.sites = 12;
  pp.approach_distance = 6;
  // (The roof spans y in [-30, 30] mm; the face, y in [-40, 40].)
  const auto under_roof = [](const ProbeSite& site) {
    return site.normal.x() > 0.7 && std::abs(site.surface_point.y()) < 0.025;
  };
  const ProbeTrajectory sphere = generate_probe_trajectory(world, pp);
  EXPECT_TRUE(std::any_of(sphere.sites().begin(), sphere.sites().end(), under_roof))
      << "the sphere reaches the +x face under the roof";
  for (const bool seen : {false, true}) {
    pp.first_touch = seen ? session::seen_first_touch(world, r) : nullptr;
    pp.tool_touch = session::tool_first_touch(world, stylus, seen);
    const ProbeTrajectory traj = generate_probe_trajectory(world, pp);
    EXPECT_GE(traj.sites().size(), 4u) << (seen ? "seen" : "ellipsoids");
    for (const ProbeSite& site : traj.sites()) {
      EXPECT_FALSE(under_roof(site)) << (seen ? "seen" : "ellipsoids") << ": site " << site.gaussian_index << " at " << site.surface_point.transpose();
      // The touch point is the tool's: from r back along the approach, the stylus meets the
      // surface after r (the ellipsoid search's step r / 8 aside), not short of the sphere's.
      const double met = pp.tool_touch(site.touch_point + r * site.normal, -site.normal, 3 * r);
      EXPECT_NEAR(met, r, r / 8 + 1e-9) << (seen ? "seen" : "ellipsoids") << ": site " << site.gaussian_index;
    }
  }
}

TEST(ProbeRun, EpisodesMergeShortGapsAndRecordPeaks) {
  std::vector<TickRecord> ticks(1000);
  for (std::size_t k = 0; k < ticks.size(); ++k) {
    ticks[k].time = double(k) * 1e-3;
    const bool touching = (k >= 100 && k < 200) || (k >= 250 && k < 300) || (k >= 700 && k < 710);
    ticks[k].counts.contacts = touching ? std::uint32_t(k % 17 + 1) : 0;
    ticks[k].force = touching ? Eigen::Vector3d(0, double(k), 0) : Eigen::Vector3d::Zero();
  }
  const auto eps = find_episodes(ticks, 0.1);
  ASSERT_EQ(eps.size(), 2u);  // the 50 ms gap is bridged, the 400 ms gap is not
  EXPECT_NEAR(eps[0].t_start, 0.100, 1e-12);
  EXPECT_NEAR(eps[0].t_end, 0.299, 1e-12);
  EXPECT_NEAR(eps[0].peak_force, 299, 1e-9);
  EXPECT_EQ(eps[0].peak_contacts, 17u);
  EXPECT_NEAR((eps[0].peak_direction - Eigen::Vector3d(0, 1, 0)).norm(), 0, 1e-12);
}

// An episode's energy W = -sum F_k . (x_k+1 - x_k) over its ticks with contacts: a constant 2 N
// against a 1 mm press in is +2 mJ; the same force held while the tool is pushed back out is
// -2 mJ (the scene gave it back); the note names the episodes that gave energy back.
TEST(ProbeRun, EpisodesCarryTheEnergyTheHandPutIn) {
  std::vector<TickRecord> ticks(600);
  for (std::size_t k = 0; k < ticks.size(); ++k) {
    TickRecord& r = ticks[k];
    r.time = double(k) * 1e-3;
    const bool first = k >= 100 && k < 200, second = k >= 400 && k < 500;
    r.counts.contacts = first || second ? 1 : 0;
    r.force = first || second ? Eigen::Vector3d(0, 0, 2.0) : Eigen::Vector3d::Zero();
    // In by 10 um a tick over the first episode, out by as much over the second.
    const double z = k < 100   ? 0.0
                     : k < 200 ? -1e-5 * double(k - 100)
                     : k < 400 ? -1e-3
                     : k < 500 ? -1e-3 + 1e-5 * double(k - 400)
                               : 0.0;
    r.position = Eigen::Vector3d(0, 0, z);
  }
  const auto eps = find_episodes(ticks, 0.1);
  ASSERT_EQ(eps.size(), 2u);
  EXPECT_NEAR(eps[0].energy_j, 2.0 * 1e-3, 1e-12);
  EXPECT_NEAR(eps[1].energy_j, -2.0 * 1e-3, 1e-12);
  EXPECT_EQ(active_episodes_note({eps[0]}), "");
  EXPECT_EQ(active_episodes_note(eps), "; 1 gave energy back, the worst W = -2.00 mJ");
}

// Every planned site is accounted for: touched (when, how hard, bounces as extra episodes) or
// missed, with how close the tool came to the planned touch point.
TEST(ProbeRun, SiteAccountsNameTouchedAndMissedSites) {
  std::vector<ProbeSite> sites(3);
  const double planned[] = {1.0, 2.0, 3.0};
  for (int i = 0; i < 3; ++i) {
    sites[i].t_touch = planned[i];
    sites[i].touch_point = Eigen::Vector3d(double(i), 0, 0);
    sites[i].surface_point = sites[i].touch_point;
    sites[i].normal = Eigen::Vector3d::UnitZ();
    sites[i].gaussian_index = std::uint32_t(i);
  }
  const ProbeTrajectory traj({{0.0, {0, 0, 1}}, {4.0, {2, 0, 1}}}, sites, 0.05);
  std::vector<TickRecord> ticks(4000);
  for (std::size_t k = 0; k < ticks.size(); ++k) {
    TickRecord& r = ticks[k];
    r.time = double(k) * 1e-3;
    r.position = Eigen::Vector3d(r.time / 2.0, 0, 0.5);  // passes 0.5 above every touch point...
    if (k >= 1800 && k < 2300) r.position.z() = 0.02;     // ...but dips to 0.02 near site 2
    // Site 1: two episodes 300 ms apart (a bounce); site 2: none although the tool came close;
    // site 3: one.
    const bool touching = (k >= 1000 && k < 1100) || (k >= 1400 && k < 1450) || (k >= 3000 && k < 3050);
    r.counts.contacts = touching ? 3 : 0;
    r.force = touching ? Eigen::Vector3d(0, 0, 0.001 * double(k % 1000 + 1)) : Eigen::Vector3d::Zero();
  }
  const auto eps = find_episodes(ticks, 0.1);
  ASSERT_EQ(eps.size(), 3u);
  const std::vector<SiteAccount> a = account_sites(traj, ticks, eps);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_TRUE(a[0].touched);
  EXPECT_NEAR(a[0].t_first_contact, 1.0, 1e-12);
  EXPECT_EQ(a[0].episodes, 2);
  EXPECT_NEAR(a[0].peak_force, 0.450, 1e-12);  // k = 1449
  EXPECT_NEAR(a[0].t_window_start, 0.0, 1e-12);
  EXPECT_NEAR(a[0].t_window_end, 1.5, 1e-12);
  EXPECT_FALSE(a[1].touched);
  EXPECT_EQ(a[1].episodes, 0);
  EXPECT_EQ(a[1].peak_force, 0.0);
  EXPECT_NEAR(a[1].closest_approach, 0.02, 1e-9);  // at t = 2.0 the tool is at (1, 0, 0.02)
  EXPECT_TRUE(a[2].touched);
  EXPECT_NEAR(a[2].t_first_contact, 3.0, 1e-12);
  EXPECT_EQ(a[2].episodes, 1);
  EXPECT_NEAR(a[2].closest_approach, std::hypot(0.5, 0.0), 1e-3);  // never dipped there
}

// A site's note says what a miss means on the renderer's own solid and names only options that
// renderer reads (the seen solid refuses the ellipsoids' --isolation-gap).
TEST(ProbeRun, AMissedSitesNoteNamesTheRenderersOwnOptions) {
  SiteAccount bounced;
  bounced.touched = true;
  bounced.episodes = 3;
  SiteAccount reached;  // came within the tool's radius, met nothing
  reached.closest_approach = 0.02;
  SiteAccount far = reached;
  far.closest_approach = 0.5;
  ProxyParams seen;
  seen.surface = ProxySurface::kSeen;
  const RendererSpec on_seen = renderer_spec(RendererKind::kProxy, seen);
  const RendererSpec on_ellipsoids = renderer_spec(RendererKind::kProxy, test::ellipsoid_params());
  const RendererSpec paper = renderer_spec(RendererKind::kPaper);
  EXPECT_EQ(site_note(bounced, 0.05, on_seen), "2 bounces");
  EXPECT_EQ(site_note(SiteAccount{.touched = true, .episodes = 1}, 0.05, on_seen), "");
  const std::string s = site_note(reached, 0.05, on_seen);
  EXPECT_EQ(s.rfind("MISSED: the tool came within 0.02 of", 0), 0u) << s;
  EXPECT_NE(s.find("no seen surface"), std::string::npos) << s;
  EXPECT_EQ(s.find("--isolation-gap"), std::string::npos) << s;
  const std::string e = site_note(reached, 0.05, on_ellipsoids);
  EXPECT_NE(e.find("met no Gaussian"), std::string::npos) << e;
  EXPECT_NE(e.find("--isolation-gap"), std::string::npos) << e;
  const std::string p = site_note(reached, 0.05, paper);
  EXPECT_EQ(p.find("--isolation-gap"), std::string::npos) << p;
  EXPECT_EQ(p.find("--surface"), std::string::npos) << p;
  for (const RendererSpec* r : {&on_seen, &on_ellipsoids, &paper})
    EXPECT_EQ(site_note(far, 0.05, *r), "MISSED: the tool never came closer than 0.5 to the planned touch point");
}

TEST(ProbeRun, CsvLogIsWrittenAtomicallyWithHeader) {
  std::vector<TickRecord> ticks(3);
  ticks[1].time = 0.001;
  ticks[1].counts = {5, 3, 2};
  ticks[1].force = {1, 2, 3};
  const std::string p = test::temp_path(".csv");
  write_tick_log_csv(p, ticks, kProbeLogColumns);
  std::ifstream in(p);
  std::string header, l0, l1;
  std::getline(in, header);
  std::getline(in, l0);
  std::getline(in, l1);
  EXPECT_EQ(header.rfind("time_s,x,y,z,vx,vy,vz,candidates,prefiltered,contacts,fx,fy,fz,", 0), 0u);
  EXPECT_NE(l1.find(",5,3,2,1.00000,2.00000,3.00000,"), std::string::npos) << l1;
  EXPECT_THROW(write_tick_log_csv("/nonexistent-dir/x.csv", ticks, kProbeLogColumns), InputError);
}

}  // namespace
}  // namespace gshaptics
