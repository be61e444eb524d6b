// Python bindings (pybind11 + NumPy) over the gshaptics C++ core: the same loaders, collision
// world, query and force model as the CLI, not a reimplementation.

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_model.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/narrowphase/k_min.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/device/device_profile.h"
#include "gshaptics/sim/pose_sampler.h"
#include "gshaptics/session/probe_session.h"
#ifdef GSHAPTICS_HAVE_OBJECTS
#include "gshaptics/session/object_session.h"
#include "gshaptics/objects/object_renderer.h"
#endif

namespace py = pybind11;
using namespace gshaptics;

namespace {

template <typename T>
using Array = py::array_t<T, py::array::c_style | py::array::forcecast>;

// Copies rows of fixed-size Eigen vectors into a new (N, K) array.
template <typename T, typename V>
Array<T> rows_to_array(const std::vector<V>& rows, py::ssize_t k) {
  Array<T> out({py::ssize_t(rows.size()), k});
  auto m = out.template mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < py::ssize_t(rows.size()); ++i)
    for (py::ssize_t j = 0; j < k; ++j) m(i, j) = T(rows[std::size_t(i)][int(j)]);
  return out;
}

template <typename T>
Array<T> vec_to_array(const std::vector<T>& v) {
  Array<T> out(py::ssize_t(v.size()));
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

// A 3-vector from any sequence/array; ValueError naming the argument otherwise.
Eigen::Vector3d vec3(const py::handle& h, const char* name) {
  Array<double> a;
  try {
    a = py::cast<Array<double>>(h);
  } catch (const py::cast_error&) {
    throw py::value_error(std::string(name) + ": expected 3 numbers");
  }
  if (a.ndim() != 1 || a.shape(0) != 3) throw py::value_error(std::string(name) + ": expected shape (3,)");
  Eigen::Vector3d v(a.at(0), a.at(1), a.at(2));
  if (!v.allFinite()) throw py::value_error(std::string(name) + ": values must be finite");
  return v;
}

Eigen::Vector4d vec4(const py::handle& h, const char* name) {
  Array<double> a = py::cast<Array<double>>(h);
  if (a.ndim() != 1 || a.shape(0) != 4) throw py::value_error(std::string(name) + ": expected shape (4,)");
  Eigen::Vector4d v(a.at(0), a.at(1), a.at(2), a.at(3));
  if (!v.allFinite()) throw py::value_error(std::string(name) + ": values must be finite");
  return v;
}

ToolEllipsoid make_tool(const Eigen::Vector3d& c, const Eigen::Vector3d& axes, const Eigen::Vector4d& q) {
  if (!(axes.minCoeff() > 0)) throw py::value_error("axes: tool semi-axes must be > 0");
  if (q.norm() < 1e-12) throw py::value_error("rotation: zero quaternion");
  ToolEllipsoid t;
  t.center = c;
  t.semi_axes = axes;
  t.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
  return t;
}

// Contacts of one query as arrays, sorted by index into the original file.
struct QueryResult {
  std::vector<std::uint32_t> index;
  std::vector<double> k_min;
  std::vector<float> opacity;
  std::vector<Eigen::Vector3d> center;
  std::uint32_t candidates = 0, prefiltered = 0, contacts = 0;
  bool overflow = false;
};

QueryResult collect(const ContactQuery& q, QueryStatus status) {
  std::vector<Contact> cs(q.result().contacts().begin(), q.result().contacts().end());
  std::sort(cs.begin(), cs.end(), [](const Contact& a, const Contact& b) { return a.index < b.index; });
  QueryResult r;
  for (const Contact& c : cs) {
    r.index.push_back(c.index);
    r.k_min.push_back(c.k_min);
    r.opacity.push_back(c.opacity);
    r.center.push_back(c.center);
  }
  r.candidates = q.result().counts.candidates;
  r.prefiltered = q.result().counts.prefiltered;
  r.contacts = q.result().counts.contacts;
  r.overflow = status == QueryStatus::kContactOverflow;
  return r;
}

// The world owns its scene-independent data; Python keeps one object.
struct PyWorld {
  std::shared_ptr<CollisionWorld> world;
  WorldBuildReport report;
  // The scene's colours (empty without): what a material map's colour regions select by.
  std::shared_ptr<const SceneColours> colours;
};

SimilarityTransform registration_from(const py::object& reg) {
  if (reg.is_none()) return {};
  if (py::isinstance<py::str>(reg)) return load_registration_file(reg.cast<std::string>());
  if (py::isinstance<py::dict>(reg)) {
    py::module_ json = py::module_::import("json");
    return parse_registration_json(json.attr("dumps")(reg).cast<std::string>(), "registration dict");
  }
  throw py::type_error("registration: expected None, a path to a JSON file or a dict");
}

// K_min of pairs given by covariances, vectorised over leading dimensions.
py::array_t<double> k_min_pairs(const Array<double>& cov_a, const Array<double>& cov_b, const Array<double>& d) {
  if (cov_a.ndim() < 2 || cov_a.shape(cov_a.ndim() - 1) != 3 || cov_a.shape(cov_a.ndim() - 2) != 3)
    throw py::value_error("cov_a: expected shape (..., 3, 3)");
  if (cov_b.ndim() != cov_a.ndim() || !std::equal(cov_a.shape(), cov_a.shape() + cov_a.ndim(), cov_b.shape()))
    throw py::value_error("cov_b: expected the same shape as cov_a");
  if (d.ndim() != cov_a.ndim() - 1 || !std::equal(d.shape(), d.shape() + d.ndim(), cov_a.shape()))
    throw py::value_error("d: expected shape (..., 3) matching cov_a's leading dimensions");
  const py::ssize_t n = d.size() / 3;
  std::vector<py::ssize_t> shape(d.shape(), d.shape() + d.ndim() - 1);
  py::array_t<double> out(shape);
  const double* A = cov_a.data();
  const double* B = cov_b.data();
  const double* D = d.data();
  double* o = out.mutable_data();
  std::string error;
  {
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n && error.empty(); ++i) {
      Eigen::Matrix3d Ma, Mb;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          Ma(r, c) = A[9 * i + 3 * r + c];
          Mb(r, c) = B[9 * i + 3 * r + c];
        }
      const Eigen::Vector3d dv(D[3 * i], D[3 * i + 1], D[3 * i + 2]);
      if (!Ma.allFinite() || !Mb.allFinite() || !dv.allFinite()) {
        error = "pair " + std::to_string(i) + ": NaN or Inf in the input";
        break;
      }
      // Factor each covariance as R diag(s^2) R^T (symmetric part; must be positive definite).
      const auto factor = [&](const Eigen::Matrix3d& M, Eigen::Matrix3d& R, Eigen::Vector3d& s, const char* name) {
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(0.5 * (M + M.transpose()));
        if (!(es.eigenvalues().minCoeff() > 0)) {
          error = "pair " + std::to_string(i) + ": " + name + " is not positive definite";
          return;
        }
        R = es.eigenvectors();
        if (R.determinant() < 0) R.col(0) *= -1;
        s = es.eigenvalues().cwiseSqrt();
      };
      Eigen::Matrix3d Ra, Rb;
      Eigen::Vector3d sa, sb;
      factor(Ma, Ra, sa, "cov_a");
      factor(Mb, Rb, sb, "cov_b");
      if (!error.empty()) break;
      o[i] = k_min(pair_coefficients(dv, Ra, sa, Rb, sb)).k_min;
    }
  }
  if (!error.empty()) throw py::value_error(error);
  return out;
}

}  // namespace

PYBIND11_MODULE(gshaptics, m) {
  m.doc() =
      "gshaptics: direct haptic rendering of 3D Gaussian Splatting scenes (Python bindings of the "
      "C++ core). Units: scene units, or metres after registration; frames: the scene's own frame, "
      "or the world frame of the registration (paper eq. 3).";
  py::register_exception<InputError>(m, "InputError", PyExc_ValueError);

  py::class_<GaussianScene, std::shared_ptr<GaussianScene>> scene(m, "Scene", py::dynamic_attr(),
      "Gaussians of a trained 3DGS scene as loaded (scene frame).");
  scene.def_static("load", [](const std::string& path, bool keep_color) {
        LoadedScene s;
        {
          py::gil_scoped_release release;
          LoadOptions lo;
          lo.keep_color = keep_color;
          s = load_scene(path, lo);
        }
        auto sp = std::make_shared<GaussianScene>(std::move(s.scene));
        py::object obj = py::cast(sp);
        const LoadReport& r = s.report;
        py::dict rep;
        rep["path"] = r.path;
        rep["format"] = std::string(to_string(r.format));
        rep["in_file"] = r.in_file;
        rep["loaded"] = r.loaded;
        rep["skipped_non_finite"] = r.skipped_non_finite;
        rep["skipped_zero_quaternion"] = r.skipped_zero_quaternion;
        rep["skipped_bad_scale"] = r.skipped_bad_scale;
        rep["sh_degree"] = r.sh_degree;
        rep["ignored_properties"] = r.ignored_properties;
        rep["frame"] = sp->frame == SceneFrame::kRub ? "RUB" : "RDF";
        obj.attr("report") = rep;
        return obj;
      },
      py::arg("path"), py::arg("keep_color") = false,
      "Loads a scene (with `keep_color`, its colour too: a material map's colour regions select by "
      "it): INRIA PLY, compressed PLY (SuperSplat/PlayCanvas), antimatter15 .splat or "
      "Niantic SPZ (gzip or zstd), detected from the content. Raises InputError (a ValueError) "
      "naming the file for missing, truncated, malformed or unsupported files. The load report "
      "is in `.report` (dict, with 'frame': 'RDF' for PLY/.splat, 'RUB' for SPZ).")
      .def("__len__", &GaussianScene::size)
      .def_property_readonly("means", [](const GaussianScene& s) { return rows_to_array<float>(s.means, 3); },
                             "(N, 3) float32 centres mu_i, scene frame")
      .def_property_readonly("scales", [](const GaussianScene& s) { return rows_to_array<float>(s.scales, 3); },
                             "(N, 3) float32 linear standard deviations (exp of the stored log-scales)")
      .def_property_readonly("rotations", [](const GaussianScene& s) { return rows_to_array<float>(s.rotations, 4); },
                             "(N, 4) float32 unit quaternions, w first")
      .def_property_readonly("opacities", [](const GaussianScene& s) { return vec_to_array(s.opacities); },
                             "(N,) float32 opacities alpha in [0, 1] (after the sigmoid)")
      .def_property_readonly("source_index", [](const GaussianScene& s) { return vec_to_array(s.source_index); },
                             "(N,) uint32 index of each Gaussian in the original file");

  py::class_<QueryResult>(m, "QueryResult",
      "Contacts of one query, sorted by index into the original file (K contacts).")
      .def_property_readonly("index", [](const QueryResult& r) { return vec_to_array(r.index); }, "(K,) uint32")
      .def_property_readonly("k_min", [](const QueryResult& r) { return vec_to_array(r.k_min); },
                             "(K,) float64 K_min in (0, 1] (paper eq. 6)")
      .def_property_readonly("opacity", [](const QueryResult& r) { return vec_to_array(r.opacity); }, "(K,) float32")
      .def_property_readonly("center", [](const QueryResult& r) { return rows_to_array<double>(r.center, 3); },
                             "(K, 3) float64 Gaussian centres, world frame")
      .def_readonly("candidates", &QueryResult::candidates, "broad-phase candidates")
      .def_readonly("prefiltered", &QueryResult::prefiltered, "after the sphere pre-filter (eq. 4)")
      .def_readonly("contacts", &QueryResult::contacts, "Gaussians with K_min > 0")
      .def_readonly("overflow", &QueryResult::overflow)
      .def("__len__", [](const QueryResult& r) { return r.index.size(); });

  py::class_<PyWorld>(m, "CollisionWorld",
      "Filtered, registered Gaussians as k-sigma ellipsoids plus the BVH broad phase. Immutable; "
      "queries may run from several threads.")
      .def(py::init([](const GaussianScene& s, float min_opacity, double sigma, const py::object& registration,
                       const std::string& up) {
             WorldConfig cfg;
             cfg.min_opacity = min_opacity;
             cfg.sigma = sigma;
             cfg.up = parse_up_axis(up, "up");
             cfg.registration = registration_from(registration);
             PyWorld w;
             py::gil_scoped_release release;
             w.world = std::make_shared<CollisionWorld>(CollisionWorld::build(s, cfg, &w.report));
             w.colours = std::make_shared<const SceneColours>(SceneColours::of(s));
             return w;
           }),
           py::arg("scene"), py::arg("min_opacity") = kDefaultMinOpacity, py::arg("sigma") = 1.0,
           py::arg("registration") = py::none(), py::arg("up") = "none",
           "Keeps Gaussians with opacity > min_opacity (paper Sec. III-A), scales ellipsoids to "
           "sigma standard deviations, turns the scene's `up` axis to +z ('none', 'auto' from the "
           "file's convention, 'y-down', 'y-up', 'z-up', 'z-down', 'x-up', 'x-down'), then "
           "registers with `registration` (None, a JSON file path, or a dict {'scale', 'rotation' "
           "[w,x,y,z] or 'matrix', 'translation'}; eq. 3).")
      .def("__len__", [](const PyWorld& w) { return w.world->size(); })
      .def_property_readonly("build_seconds", [](const PyWorld& w) { return w.report.build_seconds; })
      .def_property_readonly("memory_bytes", [](const PyWorld& w) { return w.world->memory_bytes(); })
      .def_property_readonly("bounds", [](const PyWorld& w) {
        return py::make_tuple(w.world->bounds_lo(), w.world->bounds_hi());
      }, "(lo (3,), hi (3,)) of all ellipsoids, world frame")
      .def_property_readonly("up", [](const PyWorld& w) { return w.world->up(); },
                             "(3,) the world's up (unit): the file's convention carried through `up` "
                             "and the registration; run_probe approaches along -up")
      .def_property_readonly("robust_extent", [](const PyWorld& w) { return robust_extent(*w.world); },
                             "largest 1-99 percentile extent of the centres, world units (the CLI's "
                             "default tool radius is 1 % of it)")
      .def("query", [](const PyWorld& w, const py::object& center, const py::object& axes, const py::object& rotation) {
             const ToolEllipsoid tool = make_tool(vec3(center, "center"), vec3(axes, "axes"), vec4(rotation, "rotation"));
             ContactQuery q(*w.world);
             QueryStatus st;
             {
               py::gil_scoped_release release;
               st = q.run(tool);
             }
             return collect(q, st);
           },
           py::arg("center"), py::arg("axes"), py::arg("rotation") = py::make_tuple(1.0, 0.0, 0.0, 0.0),
           "Gaussians overlapping the tool ellipsoid (centre (3,), semi-axes (3,) > 0, rotation "
           "quaternion (4,) w first; world frame). Returns a QueryResult.")
      .def("query_many", [](const PyWorld& w, const Array<double>& poses) {
             if (poses.ndim() != 2 || poses.shape(1) != 10)
               throw py::value_error("poses: expected shape (M, 10): cx cy cz ax ay az qw qx qy qz");
             std::vector<ToolEllipsoid> tools;
             auto p = poses.unchecked<2>();
             for (py::ssize_t i = 0; i < p.shape(0); ++i) {
               Eigen::Matrix<double, 10, 1> row;
               for (int k = 0; k < 10; ++k) row[k] = p(i, k);
               if (!row.allFinite()) throw py::value_error("poses: row " + std::to_string(i) + " has NaN or Inf");
               tools.push_back(make_tool(row.head<3>(), row.segment<3>(3), row.tail<4>()));
             }
             std::vector<QueryResult> out;
             {
               py::gil_scoped_release release;
               ContactQuery q(*w.world);
               for (const ToolEllipsoid& t : tools) {
                 const QueryStatus st = q.run(t);
                 out.push_back(collect(q, st));
               }
             }
             return out;
           },
           py::arg("poses"), "One query per row of an (M, 10) array; the GIL is released meanwhile.")
      .def("run_probe", [](const PyWorld& w, int sites, std::uint64_t seed, const py::object& tool_radius_obj,
                           const py::object& up, double rate_hz, const std::string& force_model,
                           const py::object& device_profile_obj) {
             // The session's probe run of `gshaptics simulate`, with its defaults (SimulateOptions):
             // 1 % of the robust extent, the world's own up, the press to half the force limit.
             session::SimulateOptions so;
             so.sites = sites;
             so.seed = seed;
             so.rate = rate_hz;
             if (!tool_radius_obj.is_none()) {
               so.tool_radius = tool_radius_obj.cast<double>();
               if (!std::isfinite(so.tool_radius) || !(so.tool_radius > 0))
                 throw py::value_error("tool_radius: must be a finite number > 0");
             }
             so.force.model = renderer_kind(force_model);
             if (!device_profile_obj.is_none())
               apply_device_profile(device_profile(device_profile_obj.cast<std::string>(), "device_profile"),
                                    so.force.f_max, so.force.proxy);
             std::optional<Eigen::Vector3d> up_axis;
             if (!up.is_none()) up_axis = vec3(up, "up");
             const session::ProbeSessionResult probe = [&] {
               py::gil_scoped_release release;
               return session::simulate_probe(*w.world, so, /*scaled=*/true, nullptr, up_axis);
             }();
             const ProbeRunResult& run = probe.run;
             const std::vector<ProbeSite>& site_list = probe.trajectory.sites();
             const std::size_t n = run.ticks.size();
             std::vector<double> time(n), query_us(n);
             std::vector<std::uint32_t> cand(n), pre(n), cont(n);
             std::vector<Eigen::Vector3d> pos(n), vel(n), force(n), user(n);
             for (std::size_t i = 0; i < n; ++i) {
               const TickRecord& t = run.ticks[i];
               time[i] = t.time;
               query_us[i] = t.query_us;
               cand[i] = t.counts.candidates;
               pre[i] = t.counts.prefiltered;
               cont[i] = t.counts.contacts;
               pos[i] = t.position;
               vel[i] = t.velocity;
               force[i] = t.force;
               user[i] = t.user_force;
             }
             py::dict d;
             d["time"] = vec_to_array(time);
             d["position"] = rows_to_array<double>(pos, 3);
             d["velocity"] = rows_to_array<double>(vel, 3);
             d["candidates"] = vec_to_array(cand);
             d["prefiltered"] = vec_to_array(pre);
             d["contacts"] = vec_to_array(cont);
             d["force"] = rows_to_array<double>(force, 3);
             d["user_force"] = rows_to_array<double>(user, 3);
             d["query_us"] = vec_to_array(query_us);
             std::vector<double> t_touch;
             for (const auto& s : site_list) t_touch.push_back(s.t_touch);
             d["site_touch_times"] = vec_to_array(t_touch);
             return d;
           },
           py::arg("sites") = ProbeParams{}.sites, py::arg("seed") = ProbeParams{}.seed, py::arg("tool_radius") = py::none(),
           py::arg("up") = py::none(), py::arg("rate_hz") = RuntimeConfig{}.rate_hz,
           py::arg("force_model") = "proxy", py::arg("device_profile") = py::none(),
           "The simulated probe run of `gshaptics simulate` (admittance device, simulated hand, "
           "inline query + force model each tick), with its defaults: tool_radius None is 1 % of "
           "the robust extent, up None is the world's up (CollisionWorld.up), device_profile None "
           "keeps the model defaults ('desktop': 3.3 N, 1000 N/m; 'room'). Returns a dict of per-tick arrays (time (T,), "
           "position/velocity/force/user_force (T, 3), candidates/prefiltered/contacts (T,), "
           "query_us (T,)) and site_touch_times.");

  py::class_<ForceParams>(m, "ForceParams", "Force-model parameters (SI units; paper eq. 7-11).")
      .def(py::init<>())
      .def_readwrite("k_base", &ForceParams::k_base, "N per contact (eq. 9-10)")
      .def_readwrite("damping", &ForceParams::damping, "D, N s/m (eq. 10)")
      .def_readwrite("f_max", &ForceParams::f_max, "N (eq. 11)")
      .def_readwrite("tau_normal", &ForceParams::tau_normal, "s, normal EMA time constant")
      .def_readwrite("tau_opacity", &ForceParams::tau_opacity, "s, opacity EMA time constant")
      .def_readwrite("tau_velocity", &ForceParams::tau_velocity, "s, velocity filter time constant");

  py::class_<ForceModel>(m, "ForceModel",
      "The paper's penalty force with per-device filter state (docs/design.md Sec. 5).")
      .def(py::init<const ForceParams&>(), py::arg("params") = ForceParams{})
      .def("update", [](ForceModel& fm, const QueryResult& r, const py::object& position,
                        const py::object& velocity, double dt) {
             if (!(dt > 0)) throw py::value_error("dt: must be > 0 seconds");
             std::vector<Contact> cs(r.index.size());
             for (std::size_t i = 0; i < cs.size(); ++i) {
               cs[i].index = r.index[i];
               cs[i].k_min = r.k_min[i];
               cs[i].opacity = r.opacity[i];
               cs[i].center = r.center[i];
             }
             const ForceOutput f = fm.update(cs, vec3(position, "position"), vec3(velocity, "velocity"), dt);
             return Eigen::Vector3d(f.force);
           },
           py::arg("contacts"), py::arg("position"), py::arg("velocity"), py::arg("dt"),
           "One tick: contacts (QueryResult), tool centre (3,) m, tool velocity (3,) m/s, dt s. "
           "Returns the force (3,) in N, world frame.")
      .def("reset", &ForceModel::reset)
      .def_property_readonly("state", [](const ForceModel& fm) {
        const ForceState& s = fm.state();
        py::dict d;
        d["n_smooth"] = Eigen::Vector3d(s.n_smooth);
        d["alpha"] = s.alpha;
        d["v_filtered"] = Eigen::Vector3d(s.v_filtered);
        d["in_contact"] = s.in_contact;
        return d;
      }, "dict: n_smooth (3,), alpha, v_filtered (3,), in_contact");

  // The proxy keeps a reference to its world: hold the world's shared_ptr beside it.
  struct PyProxy {
    std::shared_ptr<CollisionWorld> world;
    std::unique_ptr<ProxyRenderer> proxy;
    CompoundTool tool;  // the tool set_tool() was given (count 0: none yet)
  };
  py::class_<PyProxy>(m, "ProxyRenderer",
      "The proxy (god-object) force model on the Gaussians: the proxy never passes a Gaussian "
      "(continuous first contact), the device is coupled to it by k_c (N/m) and b_c (N s/m); "
      "optional Coulomb friction (mu_s, mu_k); a Gaussian with no other within isolation_gap tool "
      "radii is a floater and does not block, and so is a clump of at most floater_cluster (1-4) overlapping "
      "Gaussians with nothing else within their own size; energy_bound: the shaded normal's turns add no energy the "
      "contact's earlier turns did not take out (SpringEnergyBound); near_lists: a compound tool's sweeps read "
      "each part's near list while it rests instead of the BVH (the same contacts); device_shading: where the shaded "
      "field turns slowly it is also read where the device would rest, at most this many tool radii from the proxy "
      "(0: off); corner_normal: at a clean convex corner (three faces) the force turns to the patch's support "
      "normal; face_average: on a clean flat face a compound tool's part averages its shaded normal with the "
      "face's mean thin axis; overhang_falloff: where a disc of the other face overhangs a convex edge and "
      "blocks the tool beside it, the shaded normal leaves out that face's discs behind the face under the tool; "
      "materials: a material map (JSON, as --materials; docs/usage.md) read under the proxy (colour regions "
      "select by the colour of the scene the world was built from: Scene.load(path, keep_color=True)); "
      "f_max clamps its output (default: none, as "
      "in a runtime the safety layer limits the force); surface: the solid the proxy rests on, 'ellipsoids' or "
      "'seen' (as --surface: where the splats composite to half transmittance along the push, as a viewer sees "
      "them; build its world with min_opacity=1/255 to keep the faint Gaussians a viewer draws; the options above "
      "that serve the ellipsoids only are refused with it, by name). One per device; not thread-safe.")
      .def(py::init([](const PyWorld& w, double stiffness, double damping, double mu_s, double mu_k,
                       double f_max, bool opacity_stiffness, double isolation_gap, bool energy_bound,
                       std::size_t floater_cluster, bool near_lists, double device_shading, bool corner_normal,
                       bool face_average, bool overhang_falloff, const std::optional<std::string>& materials,
                       const std::string& surface) {
             ProxyParams p;
             p.surface = proxy_surface_from(surface, "ProxyRenderer: surface");
             p.overhang_falloff = overhang_falloff;
             p.device_shading = device_shading;
             p.corner_normal = corner_normal;
             p.isolation_gap = isolation_gap;
             p.floater_cluster = floater_cluster;
             p.energy_bound = energy_bound;
             p.near_lists = near_lists;
             p.face_average = face_average;
             p.stiffness = stiffness;
             p.damping = damping;
             p.mu_s = mu_s;
             p.mu_k = mu_k;
             p.opacity_stiffness = opacity_stiffness;
             PyProxy out{w.world, std::make_unique<ProxyRenderer>(*w.world, p, f_max), {}};
             if (materials) {
               MaterialMap map = MaterialMap::load(*materials);
               if (map.needs_colours()) map = resolve_colour_regions(map, *w.colours);  // (InputError without colour)
               out.proxy->set_materials(MaterialField::resolve(map, *w.world, p));
             }
             return out;
           }),
           py::arg("world"), py::arg("stiffness") = ProxyParams{}.stiffness,
           py::arg("damping") = ProxyParams{}.damping, py::arg("mu_s") = 0.0, py::arg("mu_k") = 0.0,
           py::arg("f_max") = ForceParams{}.f_max, py::arg("opacity_stiffness") = false,
           py::arg("isolation_gap") = ProxyParams{}.isolation_gap, py::arg("energy_bound") = ProxyParams{}.energy_bound,
           py::arg("floater_cluster") = ProxyParams{}.floater_cluster, py::arg("near_lists") = ProxyParams{}.near_lists,
           py::arg("device_shading") = ProxyParams{}.device_shading,
           py::arg("corner_normal") = ProxyParams{}.corner_normal,
           py::arg("face_average") = ProxyParams{}.face_average,
           py::arg("overhang_falloff") = ProxyParams{}.overhang_falloff, py::arg("materials") = py::none(),
           py::arg("surface") = std::string(proxy_surface_name(ProxyParams{}.surface)))
      .def("render", [](PyProxy& p, const py::object& center, const py::object& axes, const py::object& velocity,
                        double dt) {
             if (!(dt > 0)) throw py::value_error("dt: must be > 0 seconds");
             ToolEllipsoid t;
             t.center = vec3(center, "center");
             t.semi_axes = vec3(axes, "axes");
             if (!t.valid()) throw py::value_error("center/axes: finite values and axes > 0 required");
             const RenderOutput o = p.proxy->render(t, vec3(velocity, "velocity"), dt);
             return Eigen::Vector3d(o.force);
           },
           py::arg("center"), py::arg("axes"), py::arg("velocity"), py::arg("dt"),
           "One tick: device tool centre (3,) m, semi-axes (3,) m, velocity (3,) m/s, dt s. "
           "Returns the force (3,) in N, world frame.")
      .def("render_tool", [](PyProxy& p, const CompoundTool& tool, const py::object& position,
                             const py::object& rotation, const py::object& velocity,
                             const py::object& angular_velocity, double dt) {
             if (!(dt > 0)) throw py::value_error("dt: must be > 0 seconds");
             const Eigen::Vector3d x = vec3(position, "position");
             const Eigen::Vector4d q = vec4(rotation, "rotation");
             if (q.norm() < 1e-12) throw py::value_error("rotation: zero quaternion");
             // A new tool builds its proxy (and forgets the last one's state).
             bool same = tool.count == p.tool.count;
             for (int j = 0; same && j < tool.count; ++j) {
               const ToolPart &a = tool.parts[std::size_t(j)], &b = p.tool.parts[std::size_t(j)];
               same = a.offset == b.offset && a.semi_axes == b.semi_axes && a.rotation.coeffs() == b.rotation.coeffs();
             }
             if (!same) {
               p.proxy->set_tool(tool);  // validates (ValueError for a bad tool)
               p.proxy->reset();
               p.tool = tool;
             }
             std::array<ToolEllipsoid, kMaxToolParts> parts;
             const Eigen::Quaterniond qn = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
             const int n = tool.posed(x, qn, parts);
             const RenderOutput o = p.proxy->render_compound({parts.data(), std::size_t(n)}, x, vec3(velocity, "velocity"),
                                                             vec3(angular_velocity, "angular_velocity"), dt);
             std::vector<std::uint32_t> index;
             std::vector<int> part;
             for (const Contact& c : p.proxy->contacts()) {
               index.push_back(c.index);
               part.push_back(c.part);
             }
             py::dict d;
             d["force"] = Eigen::Vector3d(o.force);
             d["torque"] = Eigen::Vector3d(o.torque);
             d["proxy"] = Eigen::Vector3d(o.proxy);
             d["index"] = py::array_t<std::uint32_t>(py::ssize_t(index.size()), index.data());
             d["part"] = py::array_t<int>(py::ssize_t(part.size()), part.data());
             return d;
           },
           py::arg("tool"), py::arg("position"), py::arg("rotation"), py::arg("velocity"),
           py::arg("angular_velocity"), py::arg("dt"),
           "One tick with a tool with a shape (gshaptics.Tool): the TCP's position (3,) m, orientation "
           "(w, x, y, z) tool frame -> world, velocity (3,) m/s, angular velocity (3,) rad/s, dt s. "
           "Several parts (or one off the TCP): the compound proxy (a rigid copy of the tool no part "
           "may move into a Gaussian). Returns a dict: force (3,) N, torque (3,) N m about the TCP, "
           "proxy (3,) where it holds the TCP (m), and the Gaussians holding it: index (into the scene "
           "file) and part.")
      .def_property_readonly("proxy", [](const PyProxy& p) { return Eigen::Vector3d(p.proxy->proxy_position()); },
                             "proxy centre (3,), m, world frame")
      .def_property_readonly(
          "material",
          [](const PyProxy& p) {
            const MaterialBlend& b = p.proxy->material();
            py::dict d;
            d["name"] = p.proxy->materials() ? std::string(p.proxy->materials()->name(b.dominant)) : std::string("default");
            d["stiffness"] = b.stiffness;
            d["damping"] = b.damping;
            d["mu_s"] = b.mu_s;
            d["mu_k"] = b.mu_k;
            d["viscosity"] = b.viscosity;
            d["texture_gain"] = b.texture_gain;
            return d;
          },
          "The material under the proxy at the last tick in contact (materials=PATH: the map's blend; "
          "force/material.h): name (the largest share), stiffness N/m, damping N s/m, mu_s, mu_k, viscosity "
          "N s/m, texture_gain")
      .def_property_readonly("normal", [](const PyProxy& p) { return Eigen::Vector3d(p.proxy->contact_normal()); },
                             "shaded contact normal (3,) of the last contact")
      .def_property_readonly("sticking", [](const PyProxy& p) { return p.proxy->sticking(); })
      .def("reset", [](PyProxy& p) { p.proxy->reset(); });

  py::class_<CompoundTool>(m, "Tool",
      "A tool with a shape: 1-8 ellipsoids in the tool frame, whose origin is the device's tool "
      "centre point (collision/compound_tool.h). Tool(spec): sphere:R, ellipsoid:A,B,C, stylus:L,R "
      "(4 ellipsoids from the TCP along +z), disc:R,T or a .json file; metres. ValueError naming the "
      "spec or file when it is wrong.")
      .def(py::init([](const std::string& spec) { return parse_tool_spec(spec); }), py::arg("spec"))
      .def("__len__", [](const CompoundTool& t) { return t.count; })
      .def_property_readonly("reach", &CompoundTool::reach, "radius about the TCP holding every part, m")
      .def_property_readonly("parts", [](const CompoundTool& t) {
        py::list out;
        for (const ToolPart& p : t.view()) {
          py::dict d;
          d["center"] = Eigen::Vector3d(p.offset);
          d["semi_axes"] = Eigen::Vector3d(p.semi_axes);
          d["rotation"] = Eigen::Vector4d(p.rotation.w(), p.rotation.x(), p.rotation.y(), p.rotation.z());
          out.append(d);
        }
        return out;
      }, "list of dicts: center (3,) m and semi_axes (3,) m in the tool frame, rotation (w, x, y, z)");

  struct PyPaper {
    std::shared_ptr<CollisionWorld> world;
    std::unique_ptr<PaperRenderer> paper;
  };
  py::class_<PyPaper>(m, "PaperRenderer",
      "The paper's force model (eq. 7-11) as a renderer, for compound tools too: eq. 7-11 per part "
      "(each part with its own filters and velocity v + omega x r), the torque about the TCP "
      "sum_j (p_eff,j - x_tcp) x F_j. One per device; not thread-safe.")
      .def(py::init([](const PyWorld& w, const ForceParams& params) {
             return PyPaper{w.world, std::make_unique<PaperRenderer>(*w.world, params)};
           }),
           py::arg("world"), py::arg("params") = ForceParams{})
      .def("render", [](PyPaper& p, const CompoundTool& tool, const py::object& position, const py::object& rotation,
                        const py::object& velocity, const py::object& angular_velocity, double dt) {
             if (!(dt > 0)) throw py::value_error("dt: must be > 0 seconds");
             const Eigen::Vector3d x = vec3(position, "position");
             const Eigen::Vector4d q = vec4(rotation, "rotation");
             if (q.norm() < 1e-12) throw py::value_error("rotation: zero quaternion");
             std::array<ToolEllipsoid, kMaxToolParts> parts;
             const int n = tool.posed(x, Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized(), parts);
             const RenderOutput o = p.paper->render_compound({parts.data(), std::size_t(n)}, x, vec3(velocity, "velocity"),
                                                             vec3(angular_velocity, "angular_velocity"), dt);
             std::vector<std::uint32_t> index;
             std::vector<int> part;
             std::vector<double> k;
             for (const Contact& c : p.paper->contacts()) {
               index.push_back(c.index);
               part.push_back(c.part);
               k.push_back(c.k_min);
             }
             py::dict d;
             d["force"] = Eigen::Vector3d(o.force);
             d["torque"] = Eigen::Vector3d(o.torque);
             d["index"] = py::array_t<std::uint32_t>(py::ssize_t(index.size()), index.data());
             d["part"] = py::array_t<int>(py::ssize_t(part.size()), part.data());
             d["k_min"] = py::array_t<double>(py::ssize_t(k.size()), k.data());
             return d;
           },
           py::arg("tool"), py::arg("position"), py::arg("rotation"), py::arg("velocity"),
           py::arg("angular_velocity"), py::arg("dt"),
           "One tick: the TCP's position (3,) m, orientation (w, x, y, z) tool frame -> world, velocity "
           "(3,) m/s, angular velocity (3,) rad/s, dt s. Returns a dict: force (3,) N and torque (3,) N m "
           "about the TCP (world frame), and the contacts' index (into the scene file), part and k_min.")
      .def("reset", [](PyPaper& p) { p.paper->reset(); });

#ifdef GSHAPTICS_HAVE_OBJECTS
  // A scene with rigid objects (issue 72) as the CLI's --object makes it, for a loop of one's own.
  struct PyObjectScene {
    std::shared_ptr<CollisionWorld> world;  // the static part
    std::vector<RigidObject> objects;
    std::shared_ptr<ObjectDynamics> dynamics;
    std::unique_ptr<ObjectRenderer> renderer;
  };
  py::class_<PyObjectScene>(m, "ObjectScene",
      "A scene with rigid objects (as `--object`): the objects are cut from `scene` by their specs "
      "('box:X0,Y0,Z0,X1,Y1,Z1' world frame, m, 'indices:I,J,...', or 'file:PATH[:registration=FILE.json]' "
      "for a splat file of its own, then ':mass=KG', ':friction=MU', ':hulls=N'); `supports`: static parts of the scene "
      "('box:...', 'obox:...', 'indices:...') whose convex hulls they stand on and fall from (a table top), "
      "each keeps its Gaussians in its body frame, MuJoCo moves them on the ground fitted to the scene "
      "around them (fit_support_plane; without one, a plane under their lowest point; each cut is seated "
      "on that ground, seat_on_support), and the proxy (god-object) renders the static part and each "
      "object; each object gets the reaction of the coupling force as an external wrench. One per "
      "device; not thread-safe. Raises InputError for a bad spec or an object with no Gaussian.")
      .def(py::init([](const GaussianScene& s, const std::vector<std::string>& specs, float min_opacity, double sigma,
                       const py::object& registration, const std::string& up, double rate_hz,
                       const std::vector<std::string>& support_specs) {
             if (!(rate_hz > 0)) throw py::value_error("rate_hz: must be > 0");
             WorldConfig cfg;
             cfg.min_opacity = min_opacity;
             cfg.sigma = sigma;
             cfg.up = parse_up_axis(up, "up");
             cfg.registration = registration_from(registration);
             std::vector<ObjectSpec> parsed, held;
             for (const std::string& t : specs) parsed.push_back(parse_object_spec(t, "ObjectScene"));
             for (const std::string& t : support_specs) held.push_back(parse_object_spec(t, "ObjectScene supports"));
             if (parsed.empty()) throw py::value_error("specs: give at least one object");
             py::gil_scoped_release release;
             const SimilarityTransform T = with_up_axis(cfg.registration, cfg.up, s.frame);
             SceneCut cut = cut_objects(s, T, parsed, min_opacity);
             load_file_objects(cut, parsed, cfg.up, min_opacity);
             std::vector<RigidObject> supports;
             for (const GaussianScene& g : select_supports(cut.rest, T, held, min_opacity))
               supports.push_back(make_rigid_object(g, held[supports.size()], cfg));
             PyObjectScene out;
             out.world = std::make_shared<CollisionWorld>(CollisionWorld::build(std::move(cut.rest), cfg));
             for (std::size_t i = 0; i < parsed.size(); ++i)
               out.objects.push_back(make_rigid_object(cut.objects[i], parsed[i], cfg));
             DynamicsParams dp;
             dp.timestep = 1.0 / rate_hz;
             const ObjectSupport ground = object_support(*out.world, out.objects, supports);
             out.dynamics = std::make_shared<ObjectDynamics>(out.objects, ground.plane, dp);
             out.renderer = make_object_renderer(renderer_spec(RendererKind::kProxy), *out.world, out.objects, out.dynamics);
             return out;
           }),
           py::arg("scene"), py::arg("specs"), py::arg("min_opacity") = kDefaultMinOpacity, py::arg("sigma") = 1.0,
           py::arg("registration") = py::none(), py::arg("up") = "none", py::arg("rate_hz") = RuntimeConfig{}.rate_hz,
           py::arg("supports") = std::vector<std::string>{})
      .def("__len__", [](const PyObjectScene& o) { return o.objects.size(); })
      .def_property_readonly("static_size", [](const PyObjectScene& o) { return o.world->size(); },
                             "Gaussians of the static part (after the filter)")
      .def_property_readonly("rest_origins", [](const PyObjectScene& o) {
             std::vector<Eigen::Vector3d> r;
             for (const RigidObject& x : o.objects) r.push_back(x.rest_origin);
             return rows_to_array<double>(r, 3);
           }, "(N, 3) each object's body origin at rest, world frame, m (the centre of its hull's box)")
      .def("render", [](PyObjectScene& o, const py::object& center, double radius, const py::object& velocity, double dt) {
             if (!(dt > 0)) throw py::value_error("dt: must be > 0 seconds");
             const ToolEllipsoid t = ToolEllipsoid::sphere(vec3(center, "center"), radius);
             if (!t.valid()) throw py::value_error("center/radius: finite values and radius > 0 required");
             const Eigen::Vector3d v = vec3(velocity, "velocity");
             RenderOutput out;
             {
               py::gil_scoped_release release;
               out = o.renderer->render(t, v, dt);
             }
             py::dict d;
             d["force"] = Eigen::Vector3d(out.force);
             d["proxy"] = Eigen::Vector3d(out.proxy);
             d["contacts"] = out.counts.contacts;
             d["whole_scene_weight"] = o.renderer->whole_scene_weight();
             return d;
           },
           py::arg("center"), py::arg("radius"), py::arg("velocity"), py::arg("dt"),
           "One tick with a spherical tool: centre (3,) m, radius m, velocity (3,) m/s, dt s; the objects' "
           "dynamics advance by dt (MuJoCo steps of 1 / rate_hz). Returns a dict: force (3,) N on the "
           "hand, proxy (3,) m, contacts, whole_scene_weight (0-1: the share of the proxy on the whole "
           "scene, 1 while the objects near the tool stand where they settled; docs/design.md Sec. 11).")
      .def("poses", [](const PyObjectScene& o) {
             const ObjectPoses& p = o.dynamics->state();
             std::vector<Eigen::Vector3d> pos, lin, ang, f, tau;
             std::vector<Eigen::Vector4d> rot;
             for (std::size_t i = 0; i < p.count; ++i) {
               const BodyPose& b = p.poses[i];
               pos.push_back(b.position);
               rot.push_back(Eigen::Vector4d(b.rotation.w(), b.rotation.x(), b.rotation.y(), b.rotation.z()));
               lin.push_back(b.linear_velocity);
               ang.push_back(b.angular_velocity);
               f.push_back(p.wrenches[i].force);
               tau.push_back(p.wrenches[i].torque);
             }
             py::dict d;
             d["time"] = p.time;
             d["position"] = rows_to_array<double>(pos, 3);
             d["rotation"] = rows_to_array<double>(rot, 4);
             d["linear_velocity"] = rows_to_array<double>(lin, 3);
             d["angular_velocity"] = rows_to_array<double>(ang, 3);
             d["wrench_force"] = rows_to_array<double>(f, 3);
             d["wrench_torque"] = rows_to_array<double>(tau, 3);
             return d;
           },
           "The objects now: time (s), position (N, 3) of each body origin (m), rotation (N, 4) w first, "
           "linear_velocity (N, 3) m/s and angular_velocity (N, 3) rad/s, and the hand's wrench on each "
           "over the last dynamics step: wrench_force (N, 3) N and wrench_torque (N, 3) N m about its centre "
           "of mass. World frame.")
      .def("reset", [](PyObjectScene& o) { o.renderer->reset(); }, "Forgets the proxies; the objects back at rest.")
      .def("mjcf",
           [](const PyObjectScene& o) { return object_model_xml(o.objects, o.dynamics->support(), o.dynamics->params()); },
           "The objects' MuJoCo model as MJCF text (as --objects-mjcf writes it): each object a free body of its "
           "convex hulls, the supports' hulls, the ground plane and the contact options.")
      .def("untouched_drift",
           [](const PyObjectScene& o, double seconds) {
             if (!(seconds > 0) || !std::isfinite(seconds)) throw InputError("untouched_drift: seconds must be > 0");
             const UntouchedDrift d = untouched_drift(o.objects, o.dynamics->support(), o.dynamics->params(), seconds);
             py::dict out;
             out["moved"] = std::vector<double>(d.moved.begin(), d.moved.begin() + std::ptrdiff_t(o.objects.size()));
             out["turned"] = std::vector<double>(d.turned.begin(), d.turned.begin() + std::ptrdiff_t(o.objects.size()));
             return out;
           },
           py::arg("seconds") = 1.0,
           "How far each object goes untouched over `seconds` from rest, on a model of its own (the scene's "
           "objects are not moved): {'moved': m, 'turned': rad} per object. An object that falls or tips by "
           "itself does not stand on its support as cut (the commands warn past 1 cm or 5 degrees in 1 s).");

  m.def("push_scenario",
        [](double mass, double friction, double rate_hz, const std::string& force_model, bool passivity) {
          // `gshaptics simulate --scenario push`, as a library call (objects/push_scenario.h).
          session::SimulateOptions so;
          so.object_mass = mass;
          so.object_friction = friction;
          so.rate = rate_hz;
          so.force.model = renderer_kind(force_model);
          so.safety.passivity.enabled = passivity;
          const PushScenario scenario = session::push_scenario_from(so);
          const PushRun run = [&] {
            py::gil_scoped_release release;
            return run_push_scenario(scenario);
          }();
          const std::size_t n = run.samples.size();
          std::vector<double> t(n), turn(n), k(n);
          std::vector<Eigen::Vector3d> hand(n), device(n), box(n), box_v(n), push(n);
          for (std::size_t i = 0; i < n; ++i) {
            const PushSample& x = run.samples[i];
            t[i] = x.t;
            turn[i] = x.box_turn;
            k[i] = x.k_min;
            hand[i] = x.hand;
            device[i] = x.device;
            box[i] = x.box;
            box_v[i] = x.box_velocity;
            push[i] = x.push;
          }
          py::dict d;
          d["time"] = vec_to_array(t);
          d["hand"] = rows_to_array<double>(hand, 3);
          d["device"] = rows_to_array<double>(device, 3);
          d["object_position"] = rows_to_array<double>(box, 3);
          d["object_velocity"] = rows_to_array<double>(box_v, 3);
          d["object_turn"] = vec_to_array(turn);
          d["object_wrench_force"] = rows_to_array<double>(push, 3);
          d["k_min"] = vec_to_array(k);
          d["travelled"] = run.travelled;
          d["friction_felt"] = run.friction_estimate;
          d["friction_expected"] = run.friction_expected;
          d["deepest_k_min"] = run.deepest_k_min;
          d["deepest_box_depth"] = run.deepest_box_depth;
          d["lowest_energy"] = run.lowest_energy;
          d["peak_energy"] = run.peak_energy;
          return d;
        },
        py::arg("mass") = PushScenario{}.mass, py::arg("friction") = PushScenario{}.friction,
        py::arg("rate_hz") = RuntimeConfig{}.rate_hz, py::arg("force_model") = "proxy", py::arg("passivity") = true,
        "`gshaptics simulate --scenario push`: the simulated hand pushes a box of Gaussians (mass kg, "
        "Coulomb friction against the floor) across a floor of Gaussians through the servo step, MuJoCo "
        "simulating the box. Returns a dict of per-tick arrays (time (T,); hand, device, object_position, "
        "object_velocity, object_wrench_force: the coupling force on the box, N (T, 3); object_turn, rad, and "
        "k_min (T,)) and travelled (m), friction_felt and friction_expected (mu m g, N), deepest_k_min, "
        "deepest_box_depth (how far the tool at its proxy reached into the box's faces, m), lowest_energy and peak_energy (the passivity observer's, J).");
#endif
  m.def("k_min", &k_min_pairs, py::arg("cov_a"), py::arg("cov_b"), py::arg("d"),
        "K_min of the Gilitschenski-Hanebeck test for ellipsoids {x: (x-c)^T cov^-1 (x-c) <= 1}, "
        "vectorised: cov_a, cov_b (..., 3, 3) symmetric positive definite, d = c_a - c_b (..., 3). "
        "Returns (...) float64; overlap iff K_min >= 0 (paper eq. 5-6). Raises ValueError for "
        "wrong shapes, NaN/Inf or non-positive-definite covariances.");
}
