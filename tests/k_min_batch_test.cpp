// The batched narrow phase (k_min_batch) against the scalar k_min it vectorises: full and
// partial batches, lanes separated early, flat splats and the scalar redo path, and unused
// lanes that must not matter.

#include "gshaptics/narrowphase/k_min_batch.h"
#include "support/reference.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstring>
#include <random>
#include <vector>

namespace gshaptics {
namespace {

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

struct Pair {
  Eigen::Vector3d d;   // Gaussian centre - tool centre, world
  Eigen::Vector4f q;   // Gaussian rotation (w, x, y, z), unit, rounded to float as the world stores it
  Eigen::Matrix3d R;   // the matrix the kernel makes of q (rotation_from_quaternion)
  Eigen::Vector3d s;   // Gaussian semi-axes, rounded to float
};

// A uniformly random rotation as a unit quaternion (w, x, y, z), in double.
Eigen::Vector4d random_quaternion(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  const Eigen::Vector4d q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized();
}

// Rounds a unit quaternion to float as the world does and gives the pair its matrix.
void set_rotation(Pair& p, const Eigen::Vector4d& q) {
  p.q = q.cast<float>();
  double r[9];
  rotation_from_quaternion<double>(p.q[0], p.q[1], p.q[2], p.q[3], r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p.R(i, j) = r[3 * i + j];
}

struct Tool {
  Eigen::Matrix3d R;
  Eigen::Vector3d a;
};

// A pair near contact: the offset is up to 1.3x the sum of the largest semi-axes, so about half
// overlap. Every `flat_every`-th Gaussian is a flat splat (one axis 1e-7 of the others).
Pair random_pair(std::mt19937_64& rng, const Tool& tool, int i, int flat_every) {
  std::uniform_real_distribution<double> logu(-3, 0), u(0, 1);
  Pair p;
  set_rotation(p, random_quaternion(rng));
  for (int k = 0; k < 3; ++k) p.s[k] = double(float(std::pow(10.0, logu(rng))));
  if (flat_every > 0 && i % flat_every == 0) p.s[i % 3] = double(float(1e-7 * p.s.maxCoeff()));
  const double reach = p.s.maxCoeff() + tool.a.maxCoeff();
  p.d = random_rotation(rng).col(0) * reach * 1.3 * u(rng);
  return p;
}

void load(PairBatch& b, int lane, const Pair& p) {
  b.dx[lane] = p.d.x();
  b.dy[lane] = p.d.y();
  b.dz[lane] = p.d.z();
  for (int k = 0; k < 4; ++k) b.q[k][lane] = p.q[k];
  b.sx[lane] = float(p.s.x());
  b.sy[lane] = float(p.s.y());
  b.sz[lane] = float(p.s.z());
}

// Lanes past `count` hold NaN: the kernel must ignore them.
void poison_unused(PairBatch& b) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int l = b.count; l < kBatchCapacity; ++l) {
    b.dx[l] = b.dy[l] = b.dz[l] = nan;
    for (auto& row : b.q) row[l] = float(nan);
    b.sx[l] = b.sy[l] = b.sz[l] = float(nan);
  }
}

KMinResult scalar(const Tool& tool, const Pair& p, bool stop_when_separated) {
  KMinOptions o;
  o.stop_when_separated = stop_when_separated;
  return k_min(pair_coefficients(ToolFrame::from(tool.R, tool.a), p.d, p.R, p.s), o);
}

Tool random_tool(std::mt19937_64& rng, bool spherical) {
  std::uniform_real_distribution<double> logu(-2.5, -0.5);
  Tool t;
  t.R = random_rotation(rng);
  t.a = spherical ? Eigen::Vector3d::Constant(std::pow(10.0, logu(rng)))
                  : Eigen::Vector3d(std::pow(10.0, logu(rng)), std::pow(10.0, logu(rng)), std::pow(10.0, logu(rng)));
  return t;
}

// Every lane of full and partial batches (1 to kBatchCapacity lanes) matches the scalar search to the certified gap (1e-6)
// plus the scalar search's own tolerance.
TEST(KMinBatch, MatchesScalarOnFullAndPartialBatches) {
  std::mt19937_64 rng(20261122);
  PairBatch b;
  int compared = 0, overlapping = 0;
  for (int round = 0; round < 400; ++round) {
    const Tool tool = random_tool(rng, round % 2 == 0);
    const BatchTool bt = make_batch_tool(tool.R, tool.a);
    // Full batches, one-block batches and every size in between.
    b.count = round % 3 == 0 ? kBatchCapacity : round % 3 == 1 ? 1 + round % kBatchLanes : 1 + (round * 37) % kBatchCapacity;
    std::vector<Pair> pairs(std::size_t(b.count));
    for (int l = 0; l < b.count; ++l) load(b, l, pairs[l] = random_pair(rng, tool, l + round, 0));
    poison_unused(b);
    k_min_batch(b, bt, /*stop_when_separated=*/false);
    for (int l = 0; l < b.count; ++l) {
      const KMinResult ref = scalar(tool, pairs[l], false);
      ASSERT_EQ(b.separated[l], 0) << "round " << round << " lane " << l;
      ASSERT_TRUE(std::isfinite(b.k_min[l])) << "round " << round << " lane " << l;
      // A spherical tool's coefficients are evaluated in the Gaussian's frame, the scalar ones
      // in the tool's: they round differently (SphericalToolAgainstReference holds both to the
      // extended-precision K). Absolute for contacts (K <= 1), relative for far pairs.
      const double tol = bt.sphere ? 5e-6 : 2e-6;
      ASSERT_NEAR(b.k_min[l], ref.k_min, tol * std::max(1.0, std::fabs(ref.k_min)))
          << "round " << round << " lane " << l << " of " << b.count;
      ++compared;
      overlapping += ref.k_min > 0 ? 1 : 0;
    }
  }
  // The pose set really mixes overlapping and separated pairs.
  EXPECT_GT(overlapping, compared / 5);
  EXPECT_LT(overlapping, compared * 4 / 5);
}

// With early exit a lane may stop at the first K < 0 (then it is a separated pair, reported
// with a negative K); an overlapping pair is never stopped early and keeps its exact K_min.
TEST(KMinBatch, EarlySeparationOnlyForSeparatedPairs) {
  std::mt19937_64 rng(77);
  PairBatch b;
  int early = 0;
  for (int round = 0; round < 300; ++round) {
    const Tool tool = random_tool(rng, round % 3 != 0);
    const BatchTool bt = make_batch_tool(tool.R, tool.a);
    b.count = kBatchLanes - round % 4;
    Pair pairs[kBatchLanes];
    for (int l = 0; l < b.count; ++l) load(b, l, pairs[l] = random_pair(rng, tool, l, 0));
    poison_unused(b);
    k_min_batch(b, bt, /*stop_when_separated=*/true);
    for (int l = 0; l < b.count; ++l) {
      const double exact = scalar(tool, pairs[l], false).k_min;
      if (b.separated[l]) {
        ++early;
        ASSERT_LT(b.k_min[l], 0.0) << "round " << round << " lane " << l;
        ASSERT_LT(exact, 1e-6) << "separated early, but the pair overlaps: round " << round << " lane " << l;
        ASSERT_GE(b.k_min[l], exact - 2e-6 * std::max(1.0, std::fabs(exact))) << "a K below the minimum: round " << round << " lane " << l;
      } else {
        ASSERT_NEAR(b.k_min[l], exact, 2e-6) << "round " << round << " lane " << l;
      }
      // The contact decision the query makes agrees with the scalar search.
      if (std::fabs(exact) > 1e-6) {
        ASSERT_EQ(!b.separated[l] && b.k_min[l] > 0, exact > 0) << round << " " << l;
      }
    }
  }
  EXPECT_GT(early, 100);  // the early exit was exercised
}

// Flat splats (one axis 1e-7 of the others), as trained scenes have them: the float iteration
// cannot always certify these, and the scalar double search redoes them. The result is still
// the scalar one.
TEST(KMinBatch, FlatSplatsAreRedoneAndStayExact) {
  std::mt19937_64 rng(5);
  PairBatch b;
  int redone = 0;
  for (int round = 0; round < 600; ++round) {
    const Tool tool = random_tool(rng, true);
    const BatchTool bt = make_batch_tool(tool.R, tool.a);
    b.count = kBatchLanes - round % 7;
    Pair pairs[kBatchLanes];
    for (int l = 0; l < b.count; ++l) load(b, l, pairs[l] = random_pair(rng, tool, l, /*flat_every=*/1));
    poison_unused(b);
    k_min_batch(b, bt, false);
    redone += b.redone;
    ASSERT_LE(b.redone, b.count);
    for (int l = 0; l < b.count; ++l) {
      // The tool is spherical: its coefficients are rounded differently from the scalar ones
      // (Gaussian frame vs tool frame; see MatchesScalarOnFullAndPartialBatches). Far pairs
      // have K of -1e3 and below, where that rounding (~1e-8 relative) outweighs the gap.
      const double ref = scalar(tool, pairs[l], false).k_min;
      ASSERT_NEAR(b.k_min[l], ref, 5e-6 * std::max(1.0, std::fabs(ref))) << "round " << round << " lane " << l;
    }
  }
  EXPECT_GT(redone, 0) << "no flat-splat lane took the scalar redo path";
}

// A pair's K_min does not depend on where it sits in a batch or on the other pairs, to the
// last bit: the query's batches differ between a plain, a cached and a threaded query, whose
// results must be identical. Round, flat and coincident pairs; alone, at every block offset and
// deep in a full batch (where most lanes converge in the first steps and a few go on).
TEST(KMinBatch, SameBitsWhereverThePairSits) {
  std::mt19937_64 rng(11);
  const Tool tool = random_tool(rng, false);
  const BatchTool bt = make_batch_tool(tool.R, tool.a);
  std::vector<Pair> probes;
  for (int i = 0; i < 48; ++i) {
    Pair p = random_pair(rng, tool, i, /*flat_every=*/3);
    if (i % 16 == 5) p.d.setZero();
    probes.push_back(p);
  }
  PairBatch b;
  std::vector<double> alone(probes.size());
  std::vector<std::uint8_t> alone_sep(probes.size());
  for (std::size_t i = 0; i < probes.size(); ++i) {
    b.count = 1;
    load(b, 0, probes[i]);
    poison_unused(b);
    k_min_batch(b, bt, true);
    alone[i] = b.k_min[0];
    alone_sep[i] = b.separated[0];
  }
  int tails = 0;
  for (int round = 0; round < 12; ++round) {
    b.count = round % 2 == 0 ? kBatchCapacity : 17 + round * 13;
    std::vector<int> where(probes.size(), -1);
    for (int l = 0; l < b.count; ++l) load(b, l, random_pair(rng, tool, l + round, 4));
    for (std::size_t i = 0; i < probes.size(); ++i) {
      const int l = int((i * 53 + std::size_t(round) * 7) % std::size_t(b.count));
      bool taken = false;
      for (int w : where) taken = taken || w == l;
      if (taken) continue;
      where[i] = l;
      load(b, l, probes[i]);
    }
    poison_unused(b);
    k_min_batch(b, bt, true);
    tails += b.tail;
    for (std::size_t i = 0; i < probes.size(); ++i) {
      if (where[i] < 0) continue;
      const double k = b.k_min[where[i]];
      ASSERT_EQ(std::memcmp(&k, &alone[i], sizeof k), 0)
          << "pair " << i << " at lane " << where[i] << " of " << b.count << ": " << k << " vs " << alone[i];
      ASSERT_EQ(b.separated[where[i]], alone_sep[i]) << "pair " << i;
    }
  }
  EXPECT_GT(tails, 0) << "no lane went past the first steps: the tail path was not exercised";
}

// Coincident centres give K = 1 exactly (K(lambda) = 1 for all lambda), in any lane.
TEST(KMinBatch, CoincidentCentresGiveOne) {
  std::mt19937_64 rng(3);
  const Tool tool = random_tool(rng, false);
  PairBatch b;
  b.count = 5;
  for (int l = 0; l < b.count; ++l) {
    Pair p = random_pair(rng, tool, l, 0);
    if (l % 2 == 0) p.d.setZero();
    load(b, l, p);
  }
  poison_unused(b);
  k_min_batch(b, make_batch_tool(tool.R, tool.a), true);
  for (int l = 0; l < b.count; l += 2) EXPECT_EQ(b.k_min[l], 1.0) << l;
}

// The spherical tool's own coefficient form (BatchTool::sphere, Gaussian frame) and the general
// one (tool frame) against the extended-precision K of docs/design.md Sec. 3, on the hard end of
// the pairs: Gaussians up to 300 tool radii, offsets around contact. Their rounding differs
// (the Gaussians' quaternions are stored in float, a rotation error of ~1e-7), but both
// are within 5e-6 of the truth for K in [-1, 1], and the spherical form is not worse.
TEST(KMinBatch, SphericalToolAgainstReference) {
  std::mt19937_64 rng(8);
  PairBatch sphere_batch, general_batch;
  double worst_sphere = 0, worst_general = 0, sum_sphere = 0, sum_general = 0;
  int compared = 0;
  for (int round = 0; round < 60; ++round) {
    const Tool tool = random_tool(rng, true);
    const BatchTool bt = make_batch_tool(tool.R, tool.a);
    ASSERT_TRUE(bt.sphere);
    BatchTool general = bt;
    general.sphere = false;
    sphere_batch.count = kBatchLanes * 4;
    std::vector<Pair> pairs(std::size_t(sphere_batch.count));
    std::vector<Eigen::Matrix3d> exact_rotation(pairs.size());
    for (int l = 0; l < sphere_batch.count; ++l) {
      pairs[l] = random_pair(rng, tool, l, 0);
      const Eigen::Vector4d q = random_quaternion(rng);  // what the float quaternion rounds
      exact_rotation[l] = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
      set_rotation(pairs[l], q);
      load(sphere_batch, l, pairs[l]);
    }
    general_batch = sphere_batch;
    k_min_batch(sphere_batch, bt, false);
    k_min_batch(general_batch, general, false);
    const test::LMatrix3 cov_t = test::covariance(tool.R, tool.a);
    for (int l = 0; l < sphere_batch.count; ++l) {
      const double ref = test::reference_k_min(test::covariance(exact_rotation[l], pairs[l].s), cov_t, pairs[l].d);
      if (ref < -1 || ref > 1) continue;
      const double es = std::fabs(sphere_batch.k_min[l] - ref), eg = std::fabs(general_batch.k_min[l] - ref);
      ASSERT_LT(es, 5e-6) << "round " << round << " lane " << l << " K " << ref;
      ASSERT_LT(eg, 5e-6) << "round " << round << " lane " << l << " K " << ref;
      worst_sphere = std::max(worst_sphere, es);
      worst_general = std::max(worst_general, eg);
      sum_sphere += es;
      sum_general += eg;
      ++compared;
    }
  }
  ASSERT_GT(compared, 1000);
  EXPECT_LE(sum_sphere, 2 * sum_general) << "mean error, spherical form vs general form";
  EXPECT_LE(worst_sphere, 2 * worst_general + 1e-7);
}

}  // namespace
}  // namespace gshaptics
