// Force model (paper eq. 7-11, docs/design.md Sec. 5) on hand-made contact sets.

#include "gshaptics/force/force_model.h"

#include <gtest/gtest.h>

#include <cmath>

namespace gshaptics {
namespace {

Contact contact(std::uint32_t i, double k, float alpha, Eigen::Vector3d c) {
  Contact x;
  x.index = i;
  x.k_min = k;
  x.opacity = alpha;
  x.center = c;
  return x;
}

ForceParams no_smoothing() {
  ForceParams p;
  p.k_base = 1.0;
  p.damping = 0.0;
  p.f_max = 1000;
  p.tau_normal = p.tau_opacity = p.tau_velocity = 0;
  return p;
}

TEST(ForceModel, PushesFromCentroidTowardTool) {
  ForceModel m(no_smoothing());
  const std::vector<Contact> cs = {contact(0, 0.5, 1.f, {0, 0, -1}), contact(1, 0.5, 1.f, {0, 0, -3})};
  const ForceOutput f = m.update(cs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_NEAR((f.centroid - Eigen::Vector3d(0, 0, -2)).norm(), 0, 1e-12);  // equal weights
  EXPECT_NEAR((f.normal - Eigen::Vector3d(0, 0, 1)).norm(), 0, 1e-12);
  EXPECT_NEAR(f.magnitude, 2.0, 1e-12);  // k_base * alpha * N = 1 * 1 * 2
  EXPECT_NEAR((f.force - Eigen::Vector3d(0, 0, 2)).norm(), 0, 1e-12);
}

TEST(ForceModel, SoftmaxWeightsFavourDeeperContacts) {
  ForceModel m(no_smoothing());
  const std::vector<Contact> cs = {contact(0, 0.9, 1.f, {1, 0, 0}), contact(1, 0.1, 0.5f, {-1, 0, 0})};
  const ForceOutput f = m.update(cs, Eigen::Vector3d(0, 5, 0), Eigen::Vector3d::Zero(), 1e-3);
  const double w0 = std::exp(0.0), w1 = std::exp(-0.8);
  EXPECT_NEAR(f.centroid.x(), (w0 - w1) / (w0 + w1), 1e-9);  // polynomial exp: ~1e-10
  EXPECT_NEAR(f.k_eff, (w0 * 1.0 + w1 * 0.5) / (w0 + w1), 1e-6);  // eq. 9 with alpha_raw
}

TEST(ForceModel, ClampsAtZeroAndFmax) {
  ForceParams p = no_smoothing();
  p.f_max = 1.5;
  ForceModel m(p);
  std::vector<Contact> cs = {contact(0, 0.5, 1.f, {0, 0, -1}), contact(1, 0.5, 1.f, {0, 0, -1})};
  EXPECT_NEAR(m.update(cs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3).magnitude, 1.5, 1e-12);

  p.f_max = 100;
  p.damping = 10;
  ForceModel d(p);
  // Moving away from the surface fast: damping exceeds the elastic term -> clamped to 0, never pulls.
  const ForceOutput f = d.update(cs, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1), 1e-3);
  EXPECT_EQ(f.magnitude, 0.0);
  EXPECT_EQ(f.force, Eigen::Vector3d::Zero());
}

TEST(ForceModel, DampingResistsMotionIntoTheSurface) {
  ForceParams p = no_smoothing();
  p.damping = 10;
  ForceModel in(p), out(p), still(p);
  const std::vector<Contact> cs = {contact(0, 0.5, 1.f, {0, 0, -1})};
  const double f_in = in.update(cs, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -0.05), 1e-3).magnitude;
  const double f_still = still.update(cs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3).magnitude;
  const double f_out = out.update(cs, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 0.05), 1e-3).magnitude;
  EXPECT_NEAR(f_in, 1.0 + 0.5, 1e-12);   // F_damp . n = -D v . n = 10 * 0.05
  EXPECT_NEAR(f_still, 1.0, 1e-12);
  EXPECT_NEAR(f_out, 1.0 - 0.5, 1e-12);
}

TEST(ForceModel, EmaOfNormalAndOpacityUsesTimeConstants) {
  ForceParams p = no_smoothing();
  p.tau_normal = 0.01;
  p.tau_opacity = 0.01;
  ForceModel m(p);
  const double dt = 1e-3, beta = 1 - std::exp(-0.1);
  m.update(std::vector<Contact>{contact(0, 0.5, 1.f, {0, 0, -1})}, Eigen::Vector3d::Zero(),
           Eigen::Vector3d::Zero(), dt);
  EXPECT_NEAR((m.state().n_smooth - Eigen::Vector3d(0, 0, 1)).norm(), 0, 1e-12);  // new contact: n = n_raw
  EXPECT_NEAR(m.state().alpha, 1.0, 1e-7);
  // Centroid jumps to the side: the normal turns only by beta of the way.
  const ForceOutput f = m.update(std::vector<Contact>{contact(0, 0.5, 0.5f, {-1, 0, 0})},
                                 Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), dt);
  const Eigen::Vector3d blended = (beta * Eigen::Vector3d(1, 0, 0) + (1 - beta) * Eigen::Vector3d(0, 0, 1)).normalized();
  EXPECT_NEAR((f.normal - blended).norm(), 0, 1e-12);
  EXPECT_NEAR(m.state().alpha, beta * 0.5 + (1 - beta) * 1.0, 1e-7);
  EXPECT_NEAR(ema_factor(0.01, 1e-3), beta, 1e-15);
  EXPECT_EQ(ema_factor(0, 1e-3), 1.0);
}

TEST(ForceModel, ContactLossResetsFilters) {
  ForceParams p = no_smoothing();
  p.tau_normal = 0.05;
  ForceModel m(p);
  m.update(std::vector<Contact>{contact(0, 0.5, 1.f, {0, 0, -1})}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  const ForceOutput none = m.update({}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(none.magnitude, 0.0);
  EXPECT_FALSE(m.state().in_contact);
  EXPECT_FALSE(m.state().has_normal);
  // The next contact starts fresh: its normal is the raw one, not blended with the old (0,0,1).
  const ForceOutput f = m.update(std::vector<Contact>{contact(0, 0.5, 1.f, {1, 0, 0})},
                                 Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_NEAR((f.normal - Eigen::Vector3d(-1, 0, 0)).norm(), 0, 1e-12);
}

TEST(ForceModel, ContactAtToolCentreGivesNoForceUntilADirectionExists) {
  ForceModel m(no_smoothing());
  const ForceOutput f = m.update(std::vector<Contact>{contact(0, 1.0, 1.f, {0, 0, 0})},
                                 Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(f.magnitude, 0.0);
  EXPECT_TRUE(f.force.allFinite());
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {
// The softmax weights use a polynomial exp on (-1, 0]: compare with libm through the centroid.
TEST(ForceModel, SoftmaxWeightsMatchLibmExp) {
  ForceParams p = no_smoothing();
  ForceModel m(p);
  std::vector<Contact> cs;
  double w_sum = 0, x_sum = 0;
  for (int i = 0; i < 50; ++i) {
    const double k = 0.02 * i + 1e-3;
    cs.push_back(contact(std::uint32_t(i), k, 1.f, {double(i), 0, -1}));
  }
  for (const auto& c : cs) {
    const double w = std::exp(c.k_min - cs.back().k_min);
    w_sum += w;
    x_sum += w * c.center.x();
  }
  const ForceOutput f = m.update(cs, Eigen::Vector3d(0, 0, 5), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_NEAR(f.centroid.x(), x_sum / w_sum, 1e-9);
}
}  // namespace
}  // namespace gshaptics
