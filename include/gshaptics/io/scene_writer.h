#pragma once
/// @file
/// Writing scenes: INRIA 3DGS binary PLY and antimatter15 .splat. Files are written to a
/// temporary name and renamed, so a failure never leaves a half-written output.

#include <string>
#include <vector>

#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// INRIA layout: x y z nx ny nz f_dc_0..2 f_rest_* opacity (logit) scale_0..2 (log) rot_0..3
/// (w, x, y, z), all float, little-endian. Colour is written when the scene has it (zeros
/// otherwise). Opacity 0 / 1 are written as logits -40 / +40. Each of `comments` becomes one
/// header comment line (line breaks replaced by spaces). Throws InputError naming `path`.
void write_inria_ply(const std::string& path, const GaussianScene& scene,
                     const std::vector<std::string>& comments = {});

/// antimatter15 layout: position and linear scale as float, RGBA bytes (colour from f_dc,
/// A = opacity), quaternion bytes (q * 128 + 128, w first). Higher SH bands are dropped.
void write_splat(const std::string& path, const GaussianScene& scene);
/// The bytes write_splat() writes (32 per Gaussian), for serving without a file.
[[nodiscard]] std::string splat_bytes(const GaussianScene& scene);

/// The coordinate convention a written file is read in: RDF for .ply and .splat (the 3DGS
/// convention every reader of those formats assumes). Throws InputError naming `path` for an
/// extension that has no writer. Writers do not convert: give them a scene already in this
/// frame (conversion_transform in scene/registration.h).
[[nodiscard]] SceneFrame output_frame(const std::string& path);

/// Chooses the writer from the extension (.ply, .splat). SPZ has no writer here: an InputError
/// says so (no SPZ encoder is packaged in Debian; Niantic's reference library is not).
void write_scene(const std::string& path, const GaussianScene& scene);

}  // namespace gshaptics
