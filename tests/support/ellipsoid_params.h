#pragma once
// The ellipsoid proxy's own tests build their parameters here: the default surface is the seen
// solid, so a test of the ellipsoid proxy (ProxyRenderer's sweep, CompoundProxy, the shaded
// normal's options) names its surface once.

#include "gshaptics/force/proxy_params.h"

namespace gshaptics::test {

/// The default ProxyParams on the Gaussians' ellipsoids (ProxySurface::kEllipsoids).
inline ProxyParams ellipsoid_params() {
  ProxyParams p;
  p.surface = ProxySurface::kEllipsoids;
  return p;
}

}  // namespace gshaptics::test
