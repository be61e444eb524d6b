#include "gshaptics/servo/object_poses.h"

#include <fmt/format.h>

#include <algorithm>

#include "gshaptics/io/atomic_file.h"

namespace gshaptics {

ObjectTrack::ObjectTrack(std::size_t objects, std::size_t capacity) : objects_(std::min(objects, kMaxObjects)) {
  times_.reserve(capacity);
  values_.reserve(capacity * objects_ * kValues);
}

void ObjectTrack::push(const ObjectPoses& p) noexcept {
  if (times_.size() == times_.capacity()) {
    ++dropped_;
    return;
  }
  times_.push_back(p.time);
  for (std::size_t i = 0; i < objects_; ++i) {
    const BodyPose& b = p.poses[i];
    const Eigen::Vector3d& f = p.wrenches[i].force;
    for (const double v : {b.position.x(), b.position.y(), b.position.z(), b.rotation.w(), b.rotation.x(),
                           b.rotation.y(), b.rotation.z(), f.x(), f.y(), f.z()})
      values_.push_back(float(v));
  }
}

void ObjectTrack::write_csv(const std::string& path) const {
  std::string out = "time_s";
  for (std::size_t i = 0; i < objects_; ++i)
    for (const char* c : {"x", "y", "z", "qw", "qx", "qy", "qz", "fx", "fy", "fz"}) out += fmt::format(",obj{}_{}", i, c);
  out += "\n";
  out.reserve(out.size() + rows() * (12 + objects_ * 110));
  for (std::size_t r = 0; r < rows(); ++r) {
    out += fmt::format("{:.6f}", times_[r]);
    for (std::size_t i = 0; i < objects_; ++i) {
      const float* v = at(r, i);
      out += fmt::format(",{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.5g},{:.5g},{:.5g}", v[0], v[1], v[2], v[3],
                         v[4], v[5], v[6], v[7], v[8], v[9]);
    }
    out += "\n";
  }
  write_file_atomically(path, out);
}

}  // namespace gshaptics
