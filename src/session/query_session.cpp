#include "gshaptics/session/query_session.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include <cctype>
#include <fmt/format.h>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/io/scene_writer.h"
#include "gshaptics/scene/opacity_filter.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/session/probe_session.h"
#include "gshaptics/sim/pose_sampler.h"

namespace gshaptics::session {

ToolEllipsoid make_tool(const Eigen::Vector3d& c, const Eigen::Vector3d& a, const Eigen::Vector4d& q,
                        const std::string& where) {
  if (!(a.minCoeff() > 0)) throw InputError(where + ": tool semi-axes must be > 0");
  if (q.norm() < 1e-9) throw InputError(where + ": tool rotation is a zero quaternion");
  ToolEllipsoid t;
  t.center = c;
  t.semi_axes = a;
  t.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
  return t;
}

std::string query_answer_json(ContactQuery& query, const ToolEllipsoid& tool) {
  const auto t0 = std::chrono::steady_clock::now();
  const QueryStatus status = query.run(tool);
  const auto t1 = std::chrono::steady_clock::now();
  std::vector<Contact> contacts(query.result().contacts().begin(), query.result().contacts().end());
  std::sort(contacts.begin(), contacts.end(),
            [](const Contact& a, const Contact& b) { return a.index < b.index; });
  nlohmann::json j;
  j["candidates"] = query.result().counts.candidates;
  j["prefiltered"] = query.result().counts.prefiltered;
  nlohmann::json arr = nlohmann::json::array();
  for (const Contact& c : contacts)
    arr.push_back({{"index", c.index},
                   {"k_min", c.k_min},
                   {"opacity", c.opacity},
                   {"center", {c.center.x(), c.center.y(), c.center.z()}}});
  j["contacts"] = std::move(arr);
  j["query_us"] = std::chrono::duration<double, std::micro>(t1 - t0).count();
  if (status == QueryStatus::kContactOverflow) j["overflow"] = true;
  return j.dump();
}

ContactChange compare_contacts(const CollisionWorld& a, const CollisionWorld& b, std::size_t poses,
                               std::uint64_t seed) {
  PoseSamplerParams pp;
  pp.count = poses;
  pp.seed = seed;
  const std::vector<ToolEllipsoid> tools = sample_poses(a, pp);
  ContactQuery qa(a), qb(b);
  ContactChange c;
  std::vector<std::uint32_t> ia, ib;
  const auto indices = [](ContactQuery& q, const ToolEllipsoid& t, std::vector<std::uint32_t>& out) {
    (void)q.run(t);
    out.clear();
    for (const Contact& k : q.result().contacts()) out.push_back(k.index);
    std::sort(out.begin(), out.end());
  };
  for (const ToolEllipsoid& t : tools) {
    indices(qa, t, ia);
    indices(qb, t, ib);
    ++c.poses;
    if (ia != ib) ++c.changed;
  }
  return c;
}

void run_query_command(const QueryCommandOptions& o) {
  if (o.poses.empty() && (o.center.empty() || o.axes.empty()))
    throw InputError("query: give --tool-center and --tool-axes, or --poses FILE");
  if (!o.poses.empty() && !o.center.empty())
    throw InputError("query: --poses and --tool-center are exclusive");
  if (!o.poses.empty() && std::filesystem::is_directory(o.poses))
    throw InputError(o.poses + ": is a folder, expected a pose file");
  if (!o.poses.empty() && !std::filesystem::exists(o.poses))
    throw InputError(o.poses + ": no such pose file");
  // stdout is the JSON; what the load did goes to stderr.
  const PreparedWorld pw = prepare_world(o.scene, false, stderr);
  const CollisionWorld& world = pw.world;
  QueryOptions qo;
  if (o.minimiser == "golden") {
    qo.narrow_phase.minimiser = Minimiser::kGoldenSection;
    qo.narrow_phase.golden_iterations = o.golden_iterations;
  }
  ContactQuery query(world, qo);
  if (o.poses.empty()) {
    const ToolEllipsoid tool =
        make_tool(parse_vec3(o.center, "--tool-center"), parse_vec3(o.axes, "--tool-axes"),
                  parse_vec4(o.rotation, "--tool-rotation"), "query");
    std::printf("%s\n", query_answer_json(query, tool).c_str());
    return;
  }
  std::ifstream in(o.poses);
  if (!in) throw InputError(o.poses + ": cannot open pose file");
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    for (const std::string& m : frame_mismatches(line, o.scene))
      std::fprintf(stderr, "gshaptics: warning: %s: the poses are in another world frame: %s\n",
                   o.poses.c_str(), m.c_str());
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::istringstream ls(line);
    std::vector<double> v;
    double x;
    while (ls >> x) v.push_back(x);
    if (!ls.eof()) throw InputError(o.poses + ": line " + std::to_string(line_no) + ": not a number");
    if (v.empty()) continue;
    const std::string where = o.poses + ": line " + std::to_string(line_no);
    if (v.size() != 10)
      throw InputError(where + ": expected 10 numbers (cx cy cz ax ay az qw qx qy qz), got " +
                       std::to_string(v.size()));
    for (double y : v)
      if (!std::isfinite(y)) throw InputError(where + ": values must be finite");
    const ToolEllipsoid tool = make_tool({v[0], v[1], v[2]}, {v[3], v[4], v[5]},
                                         {v[6], v[7], v[8], v[9]}, where);
    std::printf("%s\n", query_answer_json(query, tool).c_str());
  }
}

namespace {
std::string to_lower_ext(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  for (char& ch : e) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  return e;
}
}  // namespace

void run_convert_command(const ConvertCommandOptions& o) {
  const SceneFrame to = output_frame(o.out);  // checks the extension before the load
  const LoadedScene s = load_with_progress(o.scene.scene, o.quiet, /*keep_color=*/true);
  GaussianScene scene = s.scene;
  if (o.min_opacity >= 0.f) {
    OpacityFilterReport rep;
    scene = filter_by_opacity(scene, o.min_opacity, &rep);
    fmt::print("filter     opacity > {:.2g}: kept {} of {}\n", o.min_opacity, rep.after, rep.before);
  }
  const WorldConfig cfg = world_config_from(o.scene);
  if (rotates_twice(cfg.registration, cfg.up))
    fmt::print(stderr, "warning: --up {} and the registration's rotation both turn the scene\n",
               to_string(cfg.up));
  // The written file is in its format's own convention, so that it gives the same world under
  // --up auto as the source does under these options.
  const SimilarityTransform t = conversion_transform(cfg.registration, cfg.up, scene.frame, to);
  if (!t.is_identity()) scene = transform_scene(scene, t);
  scene.frame = to;
  write_scene(o.out, scene);
  if (to_lower_ext(o.out) == ".splat") {
    // Measure what the bytes cost: the contacts of seeded tool poses, source against output.
    const LoadedScene back = load_scene(o.out);
    const CollisionWorld a = CollisionWorld::build(scene, WorldConfig{});
    const CollisionWorld b = CollisionWorld::build(back.scene, WorldConfig{});
    const ContactChange c = compare_contacts(a, b);
    fmt::print(stderr,
               "warning: .splat is lossy (rotations in 4 bytes, opacity in 1): the contacts changed for {} "
               "of {} tool poses near the surface; convert to .ply to keep them exact\n",
               c.changed, c.poses);
  }
  fmt::print("wrote      {} ({} Gaussians{}), in {}'s convention ({}): `--up auto` on it gives the "
             "world the source gives{}\n",
             o.out, scene.size(), scene.colors_dc.empty() ? ", no colour" : "",
             std::filesystem::path(o.out).extension().string(), to_string(to),
             cfg.up == UpAxis::kNone && cfg.registration.is_identity() ? " with --up auto"
                                                                        : " with these options");
}

}  // namespace gshaptics::session
