#include "gshaptics/session/serve_session.h"

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "gshaptics/error.h"
#include "gshaptics/io/mapped_file.h"
#include "gshaptics/io/scene_writer.h"
#include "gshaptics/scene/scene_cut.h"
#include "gshaptics/percentile.h"

namespace gshaptics::session {

namespace {

// Addresses a browser can reach the viewer at: `host` itself, or for a wildcard bind (0.0.0.0,
// ::) this machine's non-loopback IPv4 addresses, then its host name, then 127.0.0.1.
std::vector<std::string> reachable_hosts(const std::string& host) {
  if (host != "0.0.0.0" && host != "::" && !host.empty()) return {host};
  std::vector<std::string> out;
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) == 0) {
    for (const ifaddrs* a = list; a != nullptr; a = a->ifa_next) {
      if (a->ifa_addr == nullptr || a->ifa_addr->sa_family != AF_INET || (a->ifa_flags & IFF_LOOPBACK) != 0 ||
          (a->ifa_flags & IFF_UP) == 0)
        continue;
      char buf[INET_ADDRSTRLEN] = {};
      if (inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(a->ifa_addr)->sin_addr, buf, sizeof buf))
        out.emplace_back(buf);
    }
    freeifaddrs(list);
  }
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) == 0 && name[0] != 0) out.emplace_back(name);
  out.emplace_back("127.0.0.1");
  return out;
}


std::string spark_file_type(SceneFormat f) {
  switch (f) {
    case SceneFormat::kSplat: return "splat";
    case SceneFormat::kSpz: return "spz";
    default: return "ply";
  }
}

/// The hello message: everything the page needs once (docs/viewer_protocol.md).
std::string hello_json(const PreparedWorld& pw, const SceneOptions& so, const RuntimeSetup& setup,
                       double display_hz, const MaterialMap* materials) {
  const SimilarityTransform& r = pw.world.scene_to_world();
  std::vector<double> ax[3];
  for (const auto& g : pw.world.gaussians())
    for (int k = 0; k < 3; ++k) ax[k].push_back(g.center[k]);
  nlohmann::json lo = nlohmann::json::array(), hi = nlohmann::json::array();
  for (int k = 0; k < 3; ++k) {
    lo.push_back(percentile(ax[k], 1));
    hi.push_back(percentile(ax[k], 99));
  }
  const Eigen::Vector3d up = pw.world.up();
  nlohmann::json j;
  j["type"] = "hello";
  j["protocol"] = 1;
  j["scene_url"] = "/scene";
  j["scene_name"] = std::filesystem::path(so.scene).filename().string();
  j["file_type"] = spark_file_type(pw.scene.report.format);
  j["gaussians_in_file"] = pw.scene.report.loaded + pw.scene.report.skipped();
  j["gaussians_kept"] = pw.world.size();
  j["registration"] = {{"scale", r.scale},
                       {"rotation", {r.rotation.w(), r.rotation.x(), r.rotation.y(), r.rotation.z()}},
                       {"translation", {r.translation.x(), r.translation.y(), r.translation.z()}}};
  j["up"] = {up.x(), up.y(), up.z()};
  j["bounds"] = {{"min", lo}, {"max", hi}};
  const ToolShape& ts = setup.config.tool;
  if (ts.compound.count > 0) {
    // A tool with a shape: every part in the tool frame (its origin the TCP); "axes" is the
    // largest semi-axis, the scale the page sizes its markers by.
    const double a = ts.compound.largest_semi_axis();
    nlohmann::json parts = nlohmann::json::array();
    for (const ToolPart& p : ts.compound.view())
      parts.push_back({{"center", {p.offset.x(), p.offset.y(), p.offset.z()}},
                       {"axes", {p.semi_axes.x(), p.semi_axes.y(), p.semi_axes.z()}},
                       {"rotation", {p.rotation.w(), p.rotation.x(), p.rotation.y(), p.rotation.z()}}});
    j["tool"] = {{"axes", {a, a, a}}, {"parts", parts}};
  } else {
    j["tool"] = {{"axes", {ts.semi_axes.x(), ts.semi_axes.y(), ts.semi_axes.z()}}};
  }
  j["tau_max"] = setup.config.safety.tau_max;
  j["device"] = setup.device->info().name;
  j["mouse"] = setup.mouse != nullptr && !setup.xr;
  j["xr"] = setup.xr;
  j["f_max"] = setup.config.safety.f_max;
  j["renderer"] = std::string(renderer_name(setup.config.renderer));
  j["rate_hz"] = setup.config.rate_hz;
  j["display_hz"] = display_hz;
  j["step"] = 0.5 * setup.tool_radius;
  if (setup.workspace_box) {
    const Eigen::Vector3d a = setup.workspace_box->min(), b = setup.workspace_box->max();
    j["workspace_box"] = {{"min", {a.x(), a.y(), a.z()}}, {"max", {b.x(), b.y(), b.z()}}};
  }
  if (setup.mouse != nullptr) {
    const Eigen::Vector3d p = setup.mouse_start;
    j["tool_start"] = {p.x(), p.y(), p.z()};
  }
  // The material map's regions (the page draws them on request, M).
  if (materials != nullptr) j["material_regions"] = regions_in_world(*materials, pw.world);
  return j.dump();
}

// A scene with rigid objects: the page gets the static part (file frame, the registration
// places it as it does the file) and each object (world frame at rest) as .splat bytes, their
// colour kept. The scene is read once more, with its colour (the collision world keeps none).
void add_object_splats(ViewerConfig& vc, const SceneOptions& so, const PreparedWorld& pw, const SceneObjects& objects,
                       bool quiet) {
  LoadedScene colored = load_with_progress(so.scene, quiet, /*keep_color=*/true);
  SceneCut cut = cut_objects(colored.scene, pw.world.scene_to_world(), so.objects, pw.config.min_opacity);
  load_file_objects(cut, so.objects, pw.config.up, pw.config.min_opacity);
  vc.scene_bytes = std::make_shared<const std::string>(splat_bytes(cut.rest));
  for (const GaussianScene& o : cut.objects) vc.object_splats.push_back(std::make_shared<const std::string>(splat_bytes(o)));
  vc.object_worlds = objects.bodies;
  vc.object_poses = objects.poses;
  fmt::print("viewer     the static part ({} Gaussians) and {} object(s) served as .splat, moved by their live poses\n",
             cut.rest.size(), cut.objects.size());
}

// The hello's objects: where the page loads each one, its rest origin (world, m) and its spec.
nlohmann::json objects_hello(const SceneOptions& so, const SceneObjects& objects) {
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t i = 0; i < objects.rest_origins.size(); ++i) {
    const Eigen::Vector3d& r = objects.rest_origins[i];
    list.push_back({{"url", "/object/" + std::to_string(i)},
                    {"file_type", "splat"},
                    {"rest_origin", {r.x(), r.y(), r.z()}},
                    {"spec", so.objects[i].text}});
  }
  return list;
}

}  // namespace

std::string find_web_root() {
  std::vector<std::string> candidates;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) candidates.push_back((exe.parent_path().parent_path() / "share/gshaptics/web").string());
  candidates.push_back(std::string(GSHAPTICS_INSTALL_DATADIR) + "/web");
  candidates.push_back(std::string(GSHAPTICS_SOURCE_DIR) + "/web");
  for (const std::string& p : candidates)
    if (std::filesystem::exists(p + "/index.html")) return p;
  return "";
}

int run_serve(ServeOptions o) {
  if (o.run.simulated_time) throw InputError("--simulated-time: serve runs in real time (use `run --simulated-time`)");
  const RendererSpec renderer = o.run.force.spec();
  const SceneOptions so = with_bundled_defaults(o.run.scene, "serve", renderer);
  std::unique_ptr<HapticDevice> opened = validate_runtime_options(o.run, /*allow_mouse=*/true);  // before the scene load
  prepare_run_out_dir(o.run, so);
  ViewerConfig vc;
  vc.host = o.host;
  vc.port = std::uint16_t(o.port);
  vc.display_hz = o.display_rate;
  vc.allow_origins = o.allow_origins;
  vc.limits = o.limits;
  if (!o.token.empty() && o.no_token) throw InputError("serve: --token and --no-token are exclusive");
  if (!o.token.empty() && o.token.size() < 16)
    throw InputError("serve: --token: use at least 16 characters");
  vc.token = o.token;
  const bool loopback = is_loopback_host(o.host);
  if (!loopback && vc.token.empty() && !o.no_token) vc.token = make_access_token();
  if (!loopback && o.no_token)
    fmt::print(stderr, "warning: serving on {} without a token: anyone who can reach this port can "
                       "read the scene and steer the tool (the device's target)\n", o.host);
  vc.web_root = o.web_root.empty() ? find_web_root() : o.web_root;
  vc.scene_path = so.scene;
  if (vc.web_root.empty()) throw InputError("serve: web/index.html not found; pass --web-root");
  if (!std::filesystem::exists(vc.web_root + "/node_modules/three") ||
      !std::filesystem::exists(vc.web_root + "/node_modules/@sparkjsdev/spark"))
    throw InputError("serve: " + vc.web_root + "/node_modules has no three / @sparkjsdev/spark; run "
                     "`npm ci --prefix " + vc.web_root + "` (scripts/setup.sh does)");

  const PreparedWorld pw = prepare_world(so, o.run.quiet);
  o.run.force.materials = with_scene_colours(o.run.force.materials, so.scene);
  warn_if_outside_profile(pw, o.run.force);
  RuntimeSetup setup = make_runtime_setup(o.run, so, pw, true, std::move(opened));
  vc.hello_json = hello_json(pw, so, setup, o.display_rate, o.run.force.materials.get());
  if (!setup.objects.empty()) {
    add_object_splats(vc, so, pw, setup.objects, o.run.quiet);
    nlohmann::json hello = nlohmann::json::parse(vc.hello_json);
    hello["objects"] = objects_hello(so, setup.objects);
    hello["file_type"] = "splat";  // the static part, re-packed
    vc.hello_json = hello.dump();
  }
  if (o.run.force.materials && o.run.force.model == RendererKind::kProxy)
    vc.materials = MaterialField::resolve(*o.run.force.materials, pw.world, o.run.force.proxy);
  vc.repeat_targets = !setup.xr;  // a VR controller that stops reporting must time out
  if (setup.objects.empty() && pw.scene.report.format == SceneFormat::kSpz && pw.scene.report.version >= 4) {
    // The page's splat renderer (Spark 2.2) reads SPZ as one gzip stream only: re-pack v4.
    const std::vector<std::uint8_t> gz = spz_as_gzip(MappedFile(so.scene).bytes(), so.scene);
    vc.scene_bytes = std::make_shared<const std::string>(gz.begin(), gz.end());
    fmt::print("viewer     SPZ v{} re-packed for the page as gzip SPZ v3 ({:.1f} MB, same data)\n",
               pw.scene.report.version, double(gz.size()) / 1e6);
  }
  HapticRuntime rt(pw.world, *setup.device, setup.config);
  ContactSnapshotObserver snapshots(o.display_rate, MonotonicClock::instance());
  rt.set_observer(&snapshots);
  ViewerServer server(vc, rt, pw.world, snapshots, setup.mouse, MonotonicClock::instance());
  server.start();
  fmt::print("page       {}\n", vc.web_root);
  {
    const std::string query = vc.token.empty() ? std::string() : "?token=" + vc.token;
    const std::vector<std::string> hosts = reachable_hosts(vc.host);
    fmt::print("viewer     http://{}:{}/{}  (Ctrl-C to stop{})\n", hosts.front(), server.port(), query,
               hosts.front() != vc.host ? ", listening on every interface of " + vc.host : std::string());
    for (std::size_t i = 1; i < hosts.size(); ++i) fmt::print("           http://{}:{}/{}\n", hosts[i], server.port(), query);
  }
  std::fflush(stdout);
  const bool interrupted = run_live(rt, setup.planned, o.run.quiet, [&server] {
    return fmt::format(" | clients {} | frames {}", server.stats().clients.load(),
                       server.stats().frames_sent.load());
  });
  server.stop();
  const ViewerStats& vs = server.stats();
  fmt::print("\nviewer     {} frames sent, {} dropped for slow clients, {} tool messages ({} malformed)\n",
             vs.frames_sent.load(), vs.frames_dropped.load(), vs.tool_messages.load(), vs.bad_messages.load());
  fmt::print("refused    host {}, origin {}, token {}, connections {}; limits: {} oversize frames, {} "
             "messages over the rate, {} floods closed, {} idle peers closed\n",
             vs.refused_host.load(), vs.refused_origin.load(), vs.refused_token.load(),
             vs.refused_connections.load(), vs.oversize_frames.load(), vs.rate_limited.load(),
             vs.flood_closed.load(), vs.idle_closed.load());
  nlohmann::json extra = nlohmann::json::object();
  extra["viewer"] = to_json(vs);
  if (setup.mouse != nullptr) {
    // With the page as the device, the watchdog counts the time no page steered the tool.
    const RuntimeSummary s = rt.summary();
    const double idle = double(s.watchdog_ticks) / std::max(1.0, s.rate_hz);
    extra["device_idle_s"] = idle;
    if (idle > 0.5) {
      const std::string note = fmt::format(
          "device idle for {:.1f} of {:.1f} s: no page was steering the tool (none open, or a "
          "hidden tab), so the watchdog held the force at zero and no new pose reached the "
          "collision worker (hence the old result age). Not a fault.", idle, s.duration_s);
      extra["device_idle_note"] = note;
    }
  }
  const int rc = write_run_outputs(rt, o.run, so, pw, setup, interrupted, "serve", extra);
  if (extra.contains("device_idle_note"))
    fmt::print("note       {}\n", extra["device_idle_note"].get<std::string>());
  return rc;
}

}  // namespace gshaptics::session
