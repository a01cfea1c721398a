#pragma once
// Phantom images: analytic solids voxelised into binary label volumes (0/1),
// as a segmentation would give them, staircase included. Each shape knows its
// analytic surface, so tests can measure distances to it.

#include "core/vec3.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace scalemesh {

// An analytic solid in physical coordinates (mm).
class Shape {
public:
    virtual ~Shape() = default;
    // Negative inside, positive outside, zero on the surface. Exact Euclidean
    // distance for sphere, torus and infinite-tube parts; for unions and
    // differences a value with the right sign whose magnitude may under- or
    // over-estimate the distance away from the surface.
    virtual double sdf(const Vec3& p) const = 0;
    // A box that contains the solid.
    virtual void bounds(Vec3& lo, Vec3& hi) const = 0;
    // Topology of the boundary surface: closed components and the sum of
    // their Euler characteristics (2 - 2g each).
    virtual int components() const = 0;
    virtual int euler_characteristic() const = 0;
    // Volume of the solid (mm^3) where it has a closed form, else NaN.
    virtual double volume() const;
};

struct PhantomParams {
    double voxel_size = 0.5; // mm, edge of a cubic voxel
    double noise = 0.0;      // amplitude of per-voxel noise added to the sdf, in voxel widths (0: none)
    uint64_t seed = 1;       // seed of the noise
};

// The shape names `scalemesh phantom` accepts, in the order --help lists them.
const std::vector<std::string>& phantom_names();

// The named shape. Shapes are sized in mm; `twin_tubes` puts its gap at 1.5
// voxel widths, so it needs the voxel size. Throws InputError on an unknown name.
std::unique_ptr<Shape> make_shape(const std::string& name, double voxel_size);

// Binary label grid: value 1 (active) inside, 0 (background) outside; voxel
// (i, j, k) spans [i h, (i+1) h] x ... so its centre is at ((i, j, k) + 1/2) h,
// as the grid's transform says; grid name "label", class fog.
// Throws InputError for a non-positive voxel size or one so small the box
// would exceed 2048 voxels per side.
openvdb::FloatGrid::Ptr voxelize(const Shape& shape, const PhantomParams& params);

} // namespace scalemesh
