#include "gshaptics/objects/object_dynamics.h"

#include <mujoco/mujoco.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>

#include "gshaptics/error.h"

namespace gshaptics {
namespace {

std::atomic<long> g_warnings{0};
// MuJoCo's default warning handler prints; on the servo thread nothing may log, so warnings are
// counted instead (ObjectDynamics::warnings()).
void count_warning(const char*) { g_warnings.fetch_add(1, std::memory_order_relaxed); }

// MuJoCo's errors (mju_error: its stack overflowing mid-step, an allocation failing) end the
// process by default, wherever the device is. Instead the handler jumps back to the
// ObjectDynamics call that ran MuJoCo (guarded()), which stops the dynamics and counts the error.
// Only MuJoCo's C frames and a lambda without destructors lie between, so nothing is skipped.
thread_local std::jmp_buf* t_on_error = nullptr;
std::atomic<long> g_errors{0};
char g_last_error[256] = "";  // written by the handler; read once the runs are over

void jump_on_error(const char* msg) {
  g_errors.fetch_add(1, std::memory_order_relaxed);
  std::strncpy(g_last_error, msg, sizeof g_last_error - 1);
  if (t_on_error != nullptr) std::longjmp(*t_on_error, 1);
  std::abort();  // MuJoCo called outside ObjectDynamics: there is nothing to go back to
}

// Runs `call` (MuJoCo calls) with MuJoCo's errors coming back here: false when one was raised.
template <class Call>
bool guarded(Call&& call) noexcept {
  std::jmp_buf jump;
  std::jmp_buf* const outer = t_on_error;
  t_on_error = &jump;
  if (setjmp(jump) != 0) {
    t_on_error = outer;
    return false;
  }
  call();
  t_on_error = outer;
  return true;
}

std::string vec(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s.precision(17);
  s << v.x() << ' ' << v.y() << ' ' << v.z();
  return s.str();
}

// Loads MJCF text through MuJoCo's virtual file system (no file touches the disk).
mjModel* load_model(const std::string& xml) {
  mjVFS vfs;
  mj_defaultVFS(&vfs);
  const char* name = "gshaptics_objects.xml";
  if (mj_makeEmptyFileVFS(&vfs, name, int(xml.size())) != 0) throw InputError("objects: MuJoCo's file system is full");
  std::memcpy(vfs.filedata[mj_findFileVFS(&vfs, name)], xml.data(), xml.size());
  char error[1000] = "";
  mjModel* model = mj_loadXML(name, &vfs, error, sizeof error);
  mj_deleteVFS(&vfs);
  if (model == nullptr) throw InputError(std::string("objects: MuJoCo rejected the objects' model: ") + error);
  return model;
}

}  // namespace

SupportPlane support_under(std::span<const RigidObject> objects, const Eigen::Vector3d& up) {
  SupportPlane plane;
  plane.normal = up.normalized();
  double lowest = std::numeric_limits<double>::infinity();
  for (const RigidObject& o : objects)
    for (const Eigen::Vector3d& p : o.hull_points) {
      const double h = plane.normal.dot(o.rest_origin + p);
      if (h < lowest) {
        lowest = h;
        plane.point = o.rest_origin + p;
      }
    }
  return plane;
}

namespace {

// The objects' footprints widened (in the plane across `up`: coordinates along u, v) and the
// band of heights (along `up`) in which the ground around them is looked for.
struct GroundWindow {
  Eigen::Vector3d u, v;
  std::vector<Eigen::AlignedBox2d> areas;
  double lo = 0, hi = 0;
  [[nodiscard]] bool contains(const Eigen::Vector3d& c, const Eigen::Vector3d& up) const {
    const double h = up.dot(c);
    if (h < lo || h > hi) return false;
    const Eigen::Vector2d q(u.dot(c), v.dot(c));
    return std::any_of(areas.begin(), areas.end(), [&q](const Eigen::AlignedBox2d& b) { return b.contains(q); });
  }
};

GroundWindow ground_window(std::span<const RigidObject> objects, const Eigen::Vector3d& up) {
  GroundWindow w;
  const std::array<Eigen::Vector3d, 2> uv = support_axes(up);
  w.u = uv[0];
  w.v = uv[1];
  double low = std::numeric_limits<double>::infinity(), high = -low;
  for (const RigidObject& o : objects) {
    Eigen::AlignedBox2d box;
    for (const Eigen::Vector3d& p : o.hull_points) {
      const Eigen::Vector3d x = o.rest_origin + p;
      box.extend(Eigen::Vector2d(w.u.dot(x), w.v.dot(x)));
      low = std::min(low, up.dot(x));
      high = std::max(high, up.dot(x));
    }
    const Eigen::Vector2d grow = (0.5 * box.sizes()).cwiseMax(0.02);
    w.areas.emplace_back(box.min() - grow, box.max() + grow);
  }
  const double band = std::max(0.25 * (high - low), 0.01);
  w.lo = low - band;
  w.hi = low + band;
  return w;
}

// Least-squares plane through `points` (centroid, normal of least spread, along `up`).
SupportPlane plane_through(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= double(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d n = eig.eigenvectors().col(0);
  if (n.dot(up) < 0) n = -n;
  return {mean, n.normalized(), {}};
}

}  // namespace

double seat_on_support(RigidObject& object, const SupportPlane& support) {
  if (object.hull_points.empty()) return 0;
  const Eigen::Vector3d n = support.normal.normalized();
  const auto height = [&](const Eigen::Vector3d& p) { return n.dot(object.rest_origin + p - support.point); };
  double lowest = std::numeric_limits<double>::infinity(), highest = -lowest;
  for (const Eigen::Vector3d& p : object.hull_points) {
    lowest = std::min(lowest, height(p));
    highest = std::max(highest, height(p));
  }
  const double size = highest - lowest;
  if (!(size > 0) || !(std::abs(lowest) > kBaseGap * size) || std::abs(lowest) > kBaseReach * size) return 0;
  if (lowest < 0) {  // sunk: the points under the ground are raised onto it
    for (Eigen::Vector3d& p : object.hull_points) p -= std::min(0.0, height(p)) * n;
    return lowest;
  }
  // Standing above it: the pieces at the bottom reach down (their points' shadows on the ground).
  const std::size_t pieces = std::max<std::size_t>(1, object.piece_ends.size());
  std::vector<Eigen::Vector3d> points;
  std::vector<std::size_t> ends;
  for (std::size_t k = 0; k < pieces; ++k) {
    const std::span<const Eigen::Vector3d> piece =
        object.piece_ends.empty() ? std::span<const Eigen::Vector3d>(object.hull_points) : object.piece(k);
    double piece_lowest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : piece) piece_lowest = std::min(piece_lowest, height(p));
    points.insert(points.end(), piece.begin(), piece.end());
    if (piece_lowest <= lowest + kBaseBand * size)
      for (const Eigen::Vector3d& p : piece) points.push_back(p - height(p) * n);
    ends.push_back(points.size());
  }
  object.hull_points = std::move(points);
  if (!object.piece_ends.empty()) object.piece_ends = std::move(ends);
  return lowest;
}

std::array<Eigen::Vector3d, 2> support_axes(const Eigen::Vector3d& normal) noexcept {
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d u = (a - n.dot(a) * n).normalized();
  return {u, n.cross(u)};
}

SupportFit fit_support_plane(const CollisionWorld& static_world, std::span<const RigidObject> objects,
                             const Eigen::Vector3d& up_in) {
  const Eigen::Vector3d up = up_in.normalized();
  SupportFit fit;
  fit.plane = support_under(objects, up);
  if (objects.empty()) return fit;
  const GroundWindow window = ground_window(objects, up);
  std::vector<Eigen::Vector3d> points;
  for (const CollisionGaussian& g : static_world.gaussians()) {
    const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
    if (g.opacity >= kHullMinOpacity && window.contains(c, up)) points.push_back(c);
  }
  constexpr std::size_t kMinPoints = 20;
  for (int round = 0; round < 3 && points.size() >= kMinPoints; ++round) {
    const SupportPlane p = plane_through(points, up);
    std::vector<double> d;
    for (const Eigen::Vector3d& x : points) d.push_back(std::abs(p.normal.dot(x - p.point)));
    std::vector<double> sorted = d;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
    const double cut = 2.5 * std::max(sorted[sorted.size() / 2], 1e-6);
    std::vector<Eigen::Vector3d> kept;
    double sum = 0;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (round == 2 || d[i] <= cut) {
        kept.push_back(points[i]);
        sum += d[i] * d[i];
      }
    if (round == 2) {
      fit.points = kept.size();
      fit.rms = std::sqrt(sum / double(std::max<std::size_t>(kept.size(), 1)));
      fit.tilt = std::acos(std::clamp(p.normal.dot(up), -1.0, 1.0));
      if (fit.tilt <= 25.0 * M_PI / 180.0) {
        fit.plane = p;
        fit.fitted = true;
      }
    }
    points = std::move(kept);
  }
  return fit;
}

void add_support_hulls(SupportPlane& plane, std::span<const RigidObject> supports) {
  for (const RigidObject& s : supports)
    for (std::size_t k = 0; k < s.piece_ends.size(); ++k) {
      std::vector<Eigen::Vector3d>& hull = plane.hulls.emplace_back();
      for (const Eigen::Vector3d& p : s.piece(k)) hull.push_back(s.rest_origin + p);
    }
}

ObjectSupport object_support(const CollisionWorld& static_world, std::vector<RigidObject>& objects,
                             std::span<const RigidObject> supports) {
  ObjectSupport out;
  out.fit = fit_support_plane(static_world, supports.empty() ? std::span<const RigidObject>(objects) : supports,
                              static_world.up());
  out.plane = out.fit.plane;
  add_support_hulls(out.plane, supports);
  out.base.assign(objects.size(), 0.0);
  if (supports.empty())
    for (std::size_t i = 0; i < objects.size(); ++i)
      if (objects[i].spec.cut != ObjectSpec::Cut::kFile) out.base[i] = seat_on_support(objects[i], out.plane);
  return out;
}

UntouchedDrift untouched_drift(std::span<const RigidObject> objects, const SupportPlane& support,
                               const DynamicsParams& params, double seconds) {
  ObjectDynamics d(objects, support, params);
  std::array<BodyPose, kMaxObjects> rest{};
  for (std::size_t i = 0; i < d.size(); ++i) rest[i] = d.pose(i);
  const long steps = std::lround(seconds / params.timestep);
  for (long k = 0; k < steps && !d.failed(); ++k) d.step();
  UntouchedDrift out;
  for (std::size_t i = 0; i < d.size(); ++i) {
    out.moved[i] = (d.pose(i).position - rest[i].position).norm();
    out.turned[i] = d.pose(i).rotation.angularDistance(rest[i].rotation);
    out.settled[i] = d.pose(i);
  }
  return out;
}

namespace {

// The MJCF text; density[i] > 0: object i's pieces weigh that density (kg/m^3) over their
// volumes, else its one hull carries its mass.
std::string model_xml(std::span<const RigidObject> objects, const SupportPlane& support, const DynamicsParams& params,
                      std::span<const double> density) {
  std::ostringstream x;
  x.precision(17);
  const Eigen::Vector3d g = -params.gravity * support.normal.normalized();
  // Friction combines by the larger of two geoms' (MuJoCo): the plane's is 0, so each object's own.
  // Contacts are stiffer than MuJoCo's default (solimp 0.95-0.99 over 1 mm instead of 0.9-0.95
  // over 1 mm): less of the soft constraints' regularisation, so a sliding box feels mu N.
  x << "<mujoco model='gshaptics_objects'>\n"
    << "  <option timestep='" << params.timestep << "' gravity='" << vec(g)
    << "' cone='elliptic' impratio='100'>\n"
    << "    <flag multiccd='enable'/>\n  </option>\n";
  if (params.stack > 0) x << "  <size nstack='" << params.stack << "'/>\n";
  x << "  <default><geom solimp='0.95 0.99 0.001'/></default>\n  <asset>\n";
  const auto mesh_name = [&](std::size_t i, std::size_t k) {
    return objects[i].piece_ends.size() <= 1 ? "hull" + std::to_string(i) : "hull" + std::to_string(i) + "_" + std::to_string(k);
  };
  for (std::size_t i = 0; i < objects.size(); ++i)
    for (std::size_t k = 0; k < std::max<std::size_t>(1, objects[i].piece_ends.size()); ++k) {
      x << "    <mesh name='" << mesh_name(i, k) << "' vertex='";
      const std::span<const Eigen::Vector3d> points =
          objects[i].piece_ends.empty() ? std::span<const Eigen::Vector3d>(objects[i].hull_points) : objects[i].piece(k);
      for (const Eigen::Vector3d& p : points) x << vec(p) << ' ';
      x << "'/>\n";
    }
  for (std::size_t k = 0; k < support.hulls.size(); ++k) {
    x << "    <mesh name='support" << k << "' vertex='";
    for (const Eigen::Vector3d& p : support.hulls[k]) x << vec(p) << ' ';
    x << "'/>\n";
  }
  x << "  </asset>\n  <worldbody>\n"
    << "    <geom name='support' type='plane' size='0 0 1' pos='" << vec(support.point) << "' zaxis='"
    << vec(support.normal) << "' friction='0 0 0'/>\n";
  for (std::size_t k = 0; k < support.hulls.size(); ++k)  // static: part of the world body
    x << "    <geom name='support" << k << "' type='mesh' mesh='support" << k << "' friction='0 0 0'/>\n";
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const double mu = objects[i].spec.friction;
    x << "    <body name='object" << i << "' pos='" << vec(objects[i].rest_origin) << "'>\n      <freejoint/>\n";
    for (std::size_t k = 0; k < std::max<std::size_t>(1, objects[i].piece_ends.size()); ++k) {
      x << "      <geom type='mesh' mesh='" << mesh_name(i, k) << "' ";
      if (density[i] > 0) x << "density='" << density[i] << "'";
      else x << "mass='" << objects[i].spec.mass << "'";
      x << " friction='" << mu << ' ' << 0.01 * mu << ' ' << 0.0002 * mu << "'/>\n";
    }
    x << "    </body>\n";
  }
  x << "  </worldbody>\n</mujoco>\n";
  return x.str();
}

}  // namespace

std::string object_model_xml(std::span<const RigidObject> objects, const SupportPlane& support,
                             const DynamicsParams& params) {
  // An object of several pieces gets its mass spread over their volumes: MuJoCo weighs them at a
  // density of 1 first, which gives their volume, then at the density that makes the mass.
  std::vector<double> density(objects.size(), 0.0);
  bool pieces = false;
  for (std::size_t i = 0; i < objects.size(); ++i)
    if (objects[i].piece_ends.size() > 1) {
      density[i] = 1.0;
      pieces = true;
    }
  if (!pieces) return model_xml(objects, support, params, density);
  mjModel* weigh = load_model(model_xml(objects, support, params, density));
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (!(density[i] > 0)) continue;
    const int b = mj_name2id(weigh, mjOBJ_BODY, ("object" + std::to_string(i)).c_str());
    const double volume = b >= 0 ? weigh->body_mass[b] : 0.0;
    if (!(volume > 0)) {
      mj_deleteModel(weigh);
      throw InputError("objects: object " + std::to_string(i) + "'s hulls have no volume");
    }
    density[i] = objects[i].spec.mass / volume;
  }
  mj_deleteModel(weigh);
  return model_xml(objects, support, params, density);
}

ObjectDynamics::ObjectDynamics(std::span<const RigidObject> objects, const SupportPlane& support,
                               const DynamicsParams& params, std::shared_ptr<ObjectPoseChannel> channel)
    : params_(params), support_(support),
      channel_(channel ? std::move(channel) : std::make_shared<ObjectPoseChannel>()) {
  if (objects.empty()) throw InputError("objects: no object to simulate");
  if (objects.size() > kMaxObjects) throw InputError("objects: at most " + std::to_string(kMaxObjects) + " objects");
  if (!(params.timestep > 0)) throw InputError("objects: the dynamics timestep must be > 0 s");
  mju_user_warning = count_warning;
  mju_user_error = jump_on_error;
  model_ = load_model(object_model_xml(objects, support, params));
  if (!guarded([this] { data_ = mj_makeData(model_); }))
    throw InputError(std::string("objects: MuJoCo could not make the model's data: ") + g_last_error);
  bodies_ = objects.size();
  for (std::size_t i = 0; i < bodies_; ++i)
    body_id_[i] = mj_name2id(model_, mjOBJ_BODY, ("object" + std::to_string(i)).c_str());
  poses_.count = std::uint32_t(bodies_);
  reset();
}

ObjectDynamics::~ObjectDynamics() {
  if (data_ != nullptr) mj_deleteData(data_);
  if (model_ != nullptr) mj_deleteModel(model_);
}

void ObjectDynamics::reset() noexcept {
  failed_ = !guarded([this] {
    mj_resetData(model_, data_);
    mj_forward(model_, data_);
  });
  if (failed_) return;
  resting_steps_ = 0;
  slept_ = false;
  clear_wrenches();
  read_poses();
  anchor_ = poses_.poses;
}

Eigen::Vector3d ObjectDynamics::center_of_mass(std::size_t i) const noexcept {
  return Eigen::Map<const Eigen::Vector3d>(data_->xipos + 3 * body_id_[i]);
}

double ObjectDynamics::mass(std::size_t i) const noexcept { return model_->body_mass[body_id_[i]]; }

void ObjectDynamics::apply_wrench(std::size_t i, const Eigen::Vector3d& force, const Eigen::Vector3d& point,
                                  const Eigen::Vector3d& couple) noexcept {
  if (i >= bodies_ || !force.allFinite() || !point.allFinite() || !couple.allFinite()) return;
  mjtNum* w = data_->xfrc_applied + 6 * body_id_[i];
  const Eigen::Vector3d torque = (point - center_of_mass(i)).cross(force) + couple;
  for (int k = 0; k < 3; ++k) {
    w[k] += force[k];
    w[3 + k] += torque[k];
  }
}

void ObjectDynamics::step() noexcept {
  if (failed_) {  // MuJoCo raised an error: the objects stay where they were
    poses_.time += params_.timestep;
    return;
  }
  bool pushed = false;
  for (std::size_t i = 0; i < bodies_; ++i) {
    const mjtNum* w = data_->xfrc_applied + 6 * body_id_[i];
    pushed = pushed || std::any_of(w, w + 6, [](mjtNum x) { return x != 0; });
  }
  slept_ = !pushed && resting_steps_ >= kSleepSteps;
  if (slept_) {
    data_->time += params_.timestep;
    poses_.time = data_->time;
    if (clear_wrenches()) channel_->write(poses_);  // the readers see the hand let go
    return;
  }
  for (std::size_t i = 0; i < bodies_; ++i) {
    const mjtNum* w = data_->xfrc_applied + 6 * body_id_[i];
    poses_.wrenches[i] = {Eigen::Vector3d(w[0], w[1], w[2]), Eigen::Vector3d(w[3], w[4], w[5])};
  }
  if (!guarded([this] { mj_step(model_, data_); })) {
    failed_ = true;
    poses_.time += params_.timestep;
    return;
  }
  for (std::size_t i = 0; i < bodies_; ++i) std::fill(data_->xfrc_applied + 6 * body_id_[i], data_->xfrc_applied + 6 * body_id_[i] + 6, 0.0);
  read_poses();
  bool resting = true;
  for (std::size_t i = 0; i < bodies_; ++i)
    resting = resting && (poses_.poses[i].position - anchor_[i].position).norm() < kRestDrift &&
              poses_.poses[i].rotation.angularDistance(anchor_[i].rotation) < kRestTurn;
  resting_steps_ = resting ? resting_steps_ + 1 : 0;
  if (!resting) anchor_ = poses_.poses;
}

void ObjectDynamics::read_poses() noexcept {
  poses_.time = data_->time;
  for (std::size_t i = 0; i < bodies_; ++i) {
    const int b = body_id_[i];
    BodyPose& p = poses_.poses[i];
    p.position = Eigen::Map<const Eigen::Vector3d>(data_->xpos + 3 * b);
    const mjtNum* q = data_->xquat + 4 * b;
    p.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
    mjtNum v[6];
    mj_objectVelocity(model_, data_, mjOBJ_BODY, b, v, 0);  // [angular; linear] at xpos, world axes
    p.angular_velocity = Eigen::Vector3d(v[0], v[1], v[2]);
    p.linear_velocity = Eigen::Vector3d(v[3], v[4], v[5]);
  }
  channel_->write(poses_);
}

bool ObjectDynamics::clear_wrenches() noexcept {
  bool any = false;
  for (std::size_t i = 0; i < bodies_; ++i) {
    AppliedWrench& w = poses_.wrenches[i];
    any = any || (w.force.array() != 0).any() || (w.torque.array() != 0).any();
    w = {};
  }
  return any;
}

long ObjectDynamics::warnings() noexcept { return g_warnings.load(std::memory_order_relaxed); }
long ObjectDynamics::errors() noexcept { return g_errors.load(std::memory_order_relaxed); }
std::string ObjectDynamics::last_error() { return g_last_error; }

}  // namespace gshaptics
