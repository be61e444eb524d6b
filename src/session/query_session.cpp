#include "gshaptics/session/query_session.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <nlohmann/json.hpp>
#include <vector>

#include "gshaptics/error.h"
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

}  // namespace gshaptics::session
