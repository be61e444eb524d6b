// Your own haptic loop on gshaptics: the bundled Truck, a 3 cm spherical tool lowered onto its
// roof at 10 cm/s, and one collision query plus the paper's force model (eq. 7-11) per 1 kHz
// tick until the first touch. Put your device's pose in and send the force out where the
// comments say.
// Usage: embed [DATA_DIR] (the folder holding truck.splat and truck.registration.json).
#include <gshaptics/collision/contact_query.h>
#include <gshaptics/force/force_model.h>
#include <gshaptics/io/scene_loader.h>

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  using namespace gshaptics;
  const std::string data = argc > 1 ? argv[1] : "data";
  WorldConfig config;  // opacity > 0.2, 1-sigma ellipsoids; scene -> world: z-up, metres (eq. 3)
  config.registration = load_registration_file(data + "/truck.registration.json");
  const CollisionWorld world = CollisionWorld::build(load_scene(data + "/truck.splat").scene, config);
  ContactQuery query(world);  // one per device: scratch and contact set, allocation-free run()
  ForceModel force_model;     // paper's defaults: k_base, damping (no F_max clamp: a runtime's safety layer limits the force)
  const double dt = 1e-3, radius = 0.03;
  const Eigen::Vector3d velocity(0, 0, -0.1);
  Eigen::Vector3d tool(0, 0, world.bounds_hi().z() + radius);  // above the truck's roof

  for (int tick = 0; tick < 60000; ++tick, tool += velocity * dt) {  // your device's pose here
    query.run(ToolEllipsoid::sphere(tool, radius));
    const ForceOutput f = force_model.update(query.result().contacts(), tool, velocity, dt);
    // Send f.force (N, world frame) to your device here; we stop at the first touch.
    if (query.result().contacts().empty()) continue;
    std::printf("t = %.3f s: tool at (%.3f, %.3f, %.3f) m touches %zu Gaussians, force (%.2f, %.2f, %.2f) N\n",
                tick * dt, tool.x(), tool.y(), tool.z(), query.result().contacts().size(), f.force.x(),
                f.force.y(), f.force.z());
    return f.force.z() > 0 ? 0 : 1;  // the truck pushes the tool back up
  }
  std::printf("no contact\n");
  return 1;
}
