#pragma once
/// @file
/// Fidelity for tools with a shape (issue 36, item 4): compound tools held at a fixed
/// orientation and pressed onto a feature of an analytic shape (a plane, or a cube's edge), with
/// the contact point, the contact normal and so the torque about the tool centre point (TCP)
/// known exactly from the tool's ellipsoids and the feature. Played through the servo step like
/// every other script (interaction.h: play_script).
///
/// The analytic answer of a case: lift the tool along the press axis `up` until no part
/// overlaps the feature; the parts that touch last (within 1 nm) are in contact, each at its
/// exact tangent point with the feature (an ellipsoid on a plane: its support point; an
/// ellipsoid on a line: the root of a quadratic, below); the resultant acts at the mean of those
/// points along the mean of their normals (a rigid tool resting on a surface along a line
/// carries its load at the line's middle). The expected torque for a commanded force F is
/// tau* = (c - x_tcp) x (|F| n), with x_tcp the TCP of the lifted (resting) tool.
///
/// Frames: world, metres; the tool frame as in compound_tool.h (the stylus runs from its tip, the
/// TCP, along +z).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <cmath>
#include <string>
#include <vector>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/fidelity/interaction.h"

namespace gshaptics {

/// The feature a case presses on: a plane (point, outward unit normal) or a straight convex edge
/// (a point on it, its unit direction).
struct ContactFeature {
  enum class Kind { kPlane, kLine };
  Kind kind = Kind::kPlane;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< plane: outward normal; line: along the edge
};

/// One 6-DoF case at one site.
struct WrenchCase {
  std::string name;        ///< e.g. "stylus tip-first 30 deg"
  ShapeKind shape = ShapeKind::kPlane;
  CompoundTool tool;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< tool frame -> world, held fixed
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  ///< unit; the press moves the TCP along -up
  Eigen::Vector3d touch = Eigen::Vector3d::Zero();  ///< TCP where the tool just touches (lift 0), m
  ContactFeature feature;
};

/// Where and how the tool touches the feature when its TCP is at `tcp`.
struct AnalyticContact {
  /// How far along `up` the tool must move to just touch (> 0: it overlaps the feature by
  /// that much along up; < 0: it is that far away). -inf: no part can touch.
  double lift = -INFINITY;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< contact point (mean over touching parts), m
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ(); ///< unit, from the feature into the tool
  int parts = 0;                                     ///< parts touching together
};

/// The analytic contact of `c.tool` at TCP `tcp` with orientation `c.orientation`, lifted along
/// `c.up` (the point is on the lifted tool). Exact: ellipsoid-plane by the support function,
/// ellipsoid-line by solving (w - h u)^T P (w - h u) = 1 for the lift h, with
/// P = A - A d d^T A / (d^T A d), A = Sigma^-1, w = p0 - centre (the Mahalanobis distance from
/// the centre to the line, minimised along the line, is 1 where the ellipsoid touches it).
[[nodiscard]] AnalyticContact analytic_contact(const WrenchCase& c, const Eigen::Vector3d& tcp);

/// The tools of the 6-DoF cases (metres).
struct WrenchTools {
  CompoundTool stylus = parse_tool_spec("stylus:0.12,0.005");  ///< a 12 cm pen, 5 mm radius
  CompoundTool disc = parse_tool_spec("disc:0.02,0.004");      ///< a 2 cm radius, 4 mm thick disc
};

/// The cases on `shape`, `sites` of each, drawn with `seed` (positions and yaw on the plane,
/// position along the edge and which top edge on the cube). Plane: "stylus tip-first 0/30/60 deg",
/// "stylus side-on" (lying on the surface, pressed sideways into it: the side, not the tip,
/// makes contact), "disc flat", "disc tilted 30 deg". Cube: "stylus across an edge" (30 deg down
/// over a top edge, touching it with its third part, about 0.6 L from the tip: pressed
/// off-centre). Other shapes: none.
[[nodiscard]] std::vector<WrenchCase> wrench_cases(ShapeKind shape, const WrenchTools& tools, int sites,
                                                   std::uint64_t seed);

/// The press of a case: from `start_off` outside along up at `speed` to `depth` past the touch
/// point, hold `hold` s, retract. Script::tool is the case's tool, every tick its orientation;
/// delta is the penetration along up. Throws InputError for non-positive values.
[[nodiscard]] Script wrench_script(const WrenchCase& c, double depth, double rate_hz, double speed = 0.02,
                                   double hold = 0.3, double start_off = 0.02);

/// Metrics of one played case.
struct WrenchMetrics {
  PressMetrics press;                    ///< stiffness, hold-through, energy (as for the sphere presses)
  std::vector<double> force_dir_deg;     ///< per tick with |F| >= 0.1 N: angle(F, analytic normal)
  std::vector<double> torque_dir_deg;    ///< per tick with |F| >= 0.5 N and an analytic lever >= 1 mm
  std::vector<double> torque_ratio;      ///< the same ticks: |tau| / min(|tau*|, tau_limit)
  std::vector<double> zero_lever_mm;     ///< ticks with |F| >= 0.5 N and a lever < 1 mm: |tau| / |F|
  double analytic_lever_mm = NAN;        ///< median |tau*| / |F|
  double deepest_part_mm = NAN;          ///< max over ticks of the lift of the tool at the renderer's proxy
};
/// `proxy`: whether the renderer holds the tool at a proxy (trace.proxy); otherwise the deepest
/// part is left NaN (the paper model's tool is the device's). `tau_limit` (N m): the torque limit
/// of the safety layer the trace went through (SafetyParams::tau_max): the hand can get at most
/// that, so the magnitude is judged against the analytic torque clipped to it (a stylus across the
/// cube's edge pressed 5 mm asks 0.7 N m of a 0.5 N m limit); +inf: the analytic torque itself.
[[nodiscard]] WrenchMetrics wrench_metrics(const WrenchCase& c, const Script& script, const ScriptTrace& trace,
                                           bool proxy, double tau_limit = INFINITY);

}  // namespace gshaptics
