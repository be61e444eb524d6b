// FCL's broad phase (dynamic AABB tree) and ellipsoid-ellipsoid narrow phase.

#include <algorithm>
#include <fcl/fcl.h>

#include "peers.h"

namespace gshaptics::peers {

struct FclPeer::Impl {
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  std::vector<std::uint32_t> index;
  fcl::DynamicAABBTreeCollisionManagerd manager;
};

namespace {
fcl::Transform3d pose_of(const Eigen::Matrix3d& R, const Eigen::Vector3d& c) {
  fcl::Transform3d tf = fcl::Transform3d::Identity();
  tf.linear() = R;
  tf.translation() = c;
  return tf;
}

struct CallbackData {
  PeerResult* out;
  const std::vector<std::uint32_t>* index;
  const fcl::CollisionObjectd* tool;
};

bool on_pair(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* user) {
  auto* data = static_cast<CallbackData*>(user);
  ++data->out->candidates;
  fcl::CollisionRequestd request;  // one contact, no contact details: a yes/no test
  fcl::CollisionResultd result;
  fcl::collide(a, b, request, result);
  if (result.isCollision()) {
    const fcl::CollisionObjectd* g = a == data->tool ? b : a;
    data->out->contacts.push_back((*data->index)[reinterpret_cast<std::uintptr_t>(g->getUserData())]);
  }
  return false;  // keep going
}
}  // namespace

FclPeer::FclPeer(const CollisionWorld& world) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  std::vector<fcl::CollisionObjectd*> raw;
  for (std::size_t k = 0; k < world.size(); ++k) {
    const auto& g = world.gaussians()[k];
    auto shape = std::make_shared<fcl::Ellipsoidd>(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
    auto obj = std::make_unique<fcl::CollisionObjectd>(
        shape, pose_of(rotation_matrix(g), Eigen::Vector3d(g.center[0], g.center[1], g.center[2])));
    obj->setUserData(reinterpret_cast<void*>(std::uintptr_t(k)));
    raw.push_back(obj.get());
    m.objects.push_back(std::move(obj));
    m.index.push_back(g.source_index);
  }
  m.manager.registerObjects(raw);
  m.manager.setup();
}

FclPeer::~FclPeer() = default;

void FclPeer::query(const ToolEllipsoid& tool, PeerResult& out) {
  out.contacts.clear();
  out.candidates = 0;
  auto shape = std::make_shared<fcl::Ellipsoidd>(tool.semi_axes.x(), tool.semi_axes.y(), tool.semi_axes.z());
  fcl::CollisionObjectd obj(shape, pose_of(tool.rotation.normalized().toRotationMatrix(), tool.center));
  obj.computeAABB();
  CallbackData data{&out, &impl_->index, &obj};
  impl_->manager.collide(&obj, &data, on_pair);
  std::sort(out.contacts.begin(), out.contacts.end());
}

}  // namespace gshaptics::peers
