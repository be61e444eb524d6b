#include "gshaptics/device/replay_device.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "gshaptics/error.h"
#include "gshaptics/io/mapped_file.h"

namespace gshaptics {

namespace {

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r' && c != ' ' && c != '\t') {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

}  // namespace

PoseLog load_pose_log(const std::string& path) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw file_error(path, "cannot open the pose log");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw file_error(path, "cannot read the pose log");
  return parse_pose_log(text.str(), path);
}

PoseLog parse_pose_log(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line)) throw file_error(path, "empty file: expected a CSV header with time_s,x,y,z");
  const std::vector<std::string> header = split_csv(line);
  const auto col = [&](const char* name) -> int {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return int(i);
    return -1;
  };
  const int it = col("time_s"), ix = col("x"), iy = col("y"), iz = col("z");
  if (it < 0 || ix < 0 || iy < 0 || iz < 0)
    throw file_error(path, "line 1: the header needs the columns time_s, x, y, z (got '" + line + "')");
  const int ivx = col("vx"), ivy = col("vy"), ivz = col("vz");
  const int iqw = col("qw"), iqx = col("qx"), iqy = col("qy"), iqz = col("qz");
  PoseLog log;
  log.has_velocity = ivx >= 0 && ivy >= 0 && ivz >= 0;
  log.has_orientation = iqw >= 0 && iqx >= 0 && iqy >= 0 && iqz >= 0;

  std::size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> f = split_csv(line);
    const auto num = [&](int i) -> double {
      if (i >= int(f.size()))
        throw file_error(path, "line " + std::to_string(line_no) + ": " + std::to_string(f.size()) +
                                   " fields, the header has " + std::to_string(header.size()));
      const std::string& s = f[std::size_t(i)];
      char* end = nullptr;
      const double v = std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size())
        throw file_error(path, "line " + std::to_string(line_no) + ", column '" + header[std::size_t(i)] +
                                   "': '" + s + "' is not a number");
      return v;
    };
    PoseLogRow r;
    r.time = num(it);
    if (!std::isfinite(r.time))
      throw file_error(path, "line " + std::to_string(line_no) + ": time_s is not finite");
    if (!log.rows.empty() && !(r.time > log.rows.back().time))
      throw file_error(path, "line " + std::to_string(line_no) + ": time_s " + f[std::size_t(it)] +
                                 " does not increase");
    r.position = {num(ix), num(iy), num(iz)};
    if (log.has_velocity) r.velocity = {num(ivx), num(ivy), num(ivz)};
    if (log.has_orientation) r.orientation = Eigen::Quaterniond(num(iqw), num(iqx), num(iqy), num(iqz));
    const bool finite = r.position.allFinite() && r.velocity.allFinite() && r.orientation.coeffs().allFinite();
    if (!finite) ++log.non_finite_rows;
    log.rows.push_back(r);
  }
  if (log.rows.empty()) throw file_error(path, "the pose log has a header but no rows");
  // Rebase to start at zero.
  const double t_first = log.rows.front().time;
  for (auto& r : log.rows) r.time -= t_first;
  if (!log.has_velocity) {
    for (std::size_t i = 0; i < log.rows.size(); ++i) {
      const std::size_t a = i == 0 ? 0 : i - 1, b = i + 1 < log.rows.size() ? i + 1 : i;
      if (a != b)
        log.rows[i].velocity = (log.rows[b].position - log.rows[a].position) / (log.rows[b].time - log.rows[a].time);
    }
  }
  return log;
}

ReplayDevice::ReplayDevice(PoseLog log, std::string name) : log_(std::move(log)) {
  if (log_.rows.empty()) throw InputError("replay device '" + name + "': the pose log has no rows");
  info_.name = std::move(name);
  info_.max_rate_hz = 100000;
}

void ReplayDevice::start(Nanos now) {
  t0_ = now;
  cursor_ = 0;
  sequence_ = 0;
  finished_ = false;
}

DeviceSample ReplayDevice::read(Nanos now) noexcept {
  const double t = to_seconds(now - t0_);
  const auto& rows = log_.rows;
  while (cursor_ + 1 < rows.size() && rows[cursor_ + 1].time <= t) ++cursor_;
  DeviceSample s;
  s.sequence = ++sequence_;
  s.stamp = now;
  const PoseLogRow& a = rows[cursor_];
  if (cursor_ + 1 >= rows.size()) {
    finished_ = t >= a.time;
    s.position = a.position;
    s.orientation = a.orientation;
    s.velocity = Eigen::Vector3d::Zero();
    return s;
  }
  const PoseLogRow& b = rows[cursor_ + 1];
  const double u = std::clamp((t - a.time) / (b.time - a.time), 0.0, 1.0);
  s.position = (1 - u) * a.position + u * b.position;
  s.velocity = (1 - u) * a.velocity + u * b.velocity;
  Eigen::Quaterniond qb = b.orientation;
  if (a.orientation.dot(qb) < 0) qb.coeffs() = -qb.coeffs();
  s.orientation.coeffs() = (1 - u) * a.orientation.coeffs() + u * qb.coeffs();
  const double n = s.orientation.coeffs().norm();
  if (n > 0) s.orientation.coeffs() /= n;
  return s;
}

}  // namespace gshaptics
