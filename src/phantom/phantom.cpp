#include "phantom/phantom.h"

#include "core/errors.h"

#include <tbb/blocked_range3d.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <numbers>

namespace scalemesh {

double Shape::volume() const { return std::numeric_limits<double>::quiet_NaN(); }

namespace {

constexpr double kPi = std::numbers::pi;

// Exact sdf of a finite cylinder with flat ends, axis from a to b.
double cylinder(const Vec3& p, const Vec3& a, const Vec3& b, double radius)
{
    const Vec3 axis = b - a;
    const double length = norm(axis);
    const Vec3 u = axis / length;
    const double along = dot(p - a, u);
    const double radial = norm((p - a) - along * u) - radius;
    const double axial = std::abs(along - 0.5 * length) - 0.5 * length;
    const double outside = std::hypot(std::max(radial, 0.0), std::max(axial, 0.0));
    return outside + std::min(std::max(radial, axial), 0.0);
}

// Exact sdf of a torus in the plane z = c.z, major radius R, minor radius r.
double torus(const Vec3& p, const Vec3& c, double R, double r)
{
    const Vec3 q = p - c;
    return std::hypot(std::hypot(q.x, q.y) - R, q.z) - r;
}

class Sphere final : public Shape {
public:
    static constexpr double R = 10.0;
    double sdf(const Vec3& p) const override { return norm(p) - R; }
    void bounds(Vec3& lo, Vec3& hi) const override { lo = {-R, -R, -R}, hi = {R, R, R}; }
    int components() const override { return 1; }
    int euler_characteristic() const override { return 2; }
    double volume() const override { return 4.0 / 3.0 * kPi * R * R * R; }
};

class Torus final : public Shape {
public:
    static constexpr double R = 10.0, r = 4.0;
    double sdf(const Vec3& p) const override { return torus(p, {}, R, r); }
    void bounds(Vec3& lo, Vec3& hi) const override { lo = {-R - r, -R - r, -r}, hi = {R + r, R + r, r}; }
    int components() const override { return 1; }
    int euler_characteristic() const override { return 0; }
    double volume() const override { return 2 * kPi * kPi * R * r * r; }
};

// Straight cylinder along z with flat ends.
class Tube final : public Shape {
public:
    static constexpr double r = 3.0, half_length = 15.0;
    double sdf(const Vec3& p) const override { return cylinder(p, {0, 0, -half_length}, {0, 0, half_length}, r); }
    void bounds(Vec3& lo, Vec3& hi) const override { lo = {-r, -r, -half_length}, hi = {r, r, half_length}; }
    int components() const override { return 1; }
    int euler_characteristic() const override { return 2; }
    double volume() const override { return kPi * r * r * 2 * half_length; }
};

// Tube whose radius narrows smoothly to half at z = 0 (a 50% stenosis).
class Stenosis final : public Shape {
public:
    static constexpr double r = 3.0, half_length = 15.0, narrowing_half_width = 5.0;
    static double radius(double z)
    {
        if (std::abs(z) >= narrowing_half_width) return r;
        return r * (1.0 - 0.25 * (1.0 + std::cos(kPi * z / narrowing_half_width)));
    }
    double sdf(const Vec3& p) const override
    {
        // Radial distance to the profile: the sign is exact, the magnitude
        // within cos(atan(0.47)) of the true distance (the profile's steepest slope).
        const double radial = std::hypot(p.x, p.y) - radius(p.z);
        const double axial = std::abs(p.z) - half_length;
        const double outside = std::hypot(std::max(radial, 0.0), std::max(axial, 0.0));
        return outside + std::min(std::max(radial, axial), 0.0);
    }
    void bounds(Vec3& lo, Vec3& hi) const override { lo = {-r, -r, -half_length}, hi = {r, r, half_length}; }
    int components() const override { return 1; }
    int euler_characteristic() const override { return 2; }
};

// A parent tube that splits into two daughters at 30 degrees either side,
// radii 3 and 1.5 mm (about 2:1), joined by a sphere at the branch point.
class Bifurcation final : public Shape {
public:
    static constexpr double parent_r = 3.0, daughter_r = 1.5, parent_length = 15.0, daughter_length = 15.0;
    static Vec3 daughter_end(int side)
    {
        const double a = kPi / 6.0;
        return {side * daughter_length * std::sin(a), 0, daughter_length * std::cos(a)};
    }
    double sdf(const Vec3& p) const override
    {
        const double parent = cylinder(p, {0, 0, -parent_length}, {0, 0, 0}, parent_r);
        const double joint = norm(p) - parent_r;
        // Daughters start inside the joint sphere and end in flat cuts.
        const double d1 = cylinder(p, {0, 0, 0}, daughter_end(-1), daughter_r);
        const double d2 = cylinder(p, {0, 0, 0}, daughter_end(+1), daughter_r);
        return std::min({parent, joint, d1, d2});
    }
    void bounds(Vec3& lo, Vec3& hi) const override
    {
        const Vec3 e = daughter_end(1);
        lo = {-e.x - daughter_r, -parent_r, -parent_length};
        hi = {e.x + daughter_r, parent_r, e.z + daughter_r};
    }
    int components() const override { return 1; }
    int euler_characteristic() const override { return 2; }
};

// Three solid tori in a row, each overlapping the next in one region: genus 3.
class Pretzel final : public Shape {
public:
    static constexpr double R = 6.0, r = 2.0, spacing = 2 * R - r;
    double sdf(const Vec3& p) const override
    {
        return std::min({torus(p, {-spacing, 0, 0}, R, r), torus(p, {0, 0, 0}, R, r), torus(p, {spacing, 0, 0}, R, r)});
    }
    void bounds(Vec3& lo, Vec3& hi) const override
    {
        lo = {-spacing - R - r, -R - r, -r};
        hi = {spacing + R + r, R + r, r};
    }
    int components() const override { return 1; }
    int euler_characteristic() const override { return -4; }
};

// A ball with two spherical cavities: one outer surface and two inner ones.
class Shell final : public Shape {
public:
    static constexpr double R = 10.0, cavity_r = 3.0, cavity_offset = 4.5;
    double sdf(const Vec3& p) const override
    {
        const double outer = norm(p) - R;
        const double c1 = cavity_r - distance(p, {-cavity_offset, 0, 0});
        const double c2 = cavity_r - distance(p, {cavity_offset, 0, 0});
        return std::max({outer, c1, c2});
    }
    void bounds(Vec3& lo, Vec3& hi) const override { lo = {-R, -R, -R}, hi = {R, R, R}; }
    int components() const override { return 3; }
    int euler_characteristic() const override { return 6; }
    double volume() const override { return 4.0 / 3.0 * kPi * (R * R * R - 2 * cavity_r * cavity_r * cavity_r); }
};

// Two parallel tubes along z whose walls are 1.5 voxel widths apart: the
// connect-across case of the paper's Fig. 10.
class TwinTubes final : public Shape {
public:
    static constexpr double r = 3.0, half_length = 10.0;
    explicit TwinTubes(double voxel_size) : half_gap_(0.75 * voxel_size) {}
    double centre_x() const { return r + half_gap_; }
    double sdf(const Vec3& p) const override
    {
        const double x = centre_x();
        return std::min(cylinder(p, {-x, 0, -half_length}, {-x, 0, half_length}, r),
                        cylinder(p, {x, 0, -half_length}, {x, 0, half_length}, r));
    }
    void bounds(Vec3& lo, Vec3& hi) const override
    {
        lo = {-centre_x() - r, -r, -half_length};
        hi = {centre_x() + r, r, half_length};
    }
    int components() const override { return 2; }
    int euler_characteristic() const override { return 4; }
    double volume() const override { return 2 * kPi * r * r * 2 * half_length; }

private:
    double half_gap_;
};

// Deterministic per-voxel noise in [-1, 1] from the voxel index and the seed.
double voxel_noise(int64_t i, int64_t j, int64_t k, uint64_t seed)
{
    uint64_t h = seed * 0x9E3779B97F4A7C15ull;
    for (int64_t v : {i, j, k}) {
        h ^= static_cast<uint64_t>(v) + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 31;
    }
    return static_cast<double>(h >> 11) / static_cast<double>(1ull << 53) * 2.0 - 1.0;
}

} // namespace

const std::vector<std::string>& phantom_names()
{
    static const std::vector<std::string> names = {"sphere",   "torus",   "tube",  "stenosis",
                                                   "bifurcation", "pretzel", "shell", "twin_tubes"};
    return names;
}

std::unique_ptr<Shape> make_shape(const std::string& name, double voxel_size)
{
    if (name == "sphere") return std::make_unique<Sphere>();
    if (name == "torus") return std::make_unique<Torus>();
    if (name == "tube") return std::make_unique<Tube>();
    if (name == "stenosis") return std::make_unique<Stenosis>();
    if (name == "bifurcation") return std::make_unique<Bifurcation>();
    if (name == "pretzel") return std::make_unique<Pretzel>();
    if (name == "shell") return std::make_unique<Shell>();
    if (name == "twin_tubes") return std::make_unique<TwinTubes>(voxel_size);
    std::string valid;
    for (const std::string& n : phantom_names()) valid += (valid.empty() ? "" : ", ") + n;
    throw InputError("unknown phantom shape '" + name + "'", "choose one of: " + valid);
}

openvdb::FloatGrid::Ptr voxelize(const Shape& shape, const PhantomParams& params)
{
    const double h = params.voxel_size;
    if (!(h > 0) || !std::isfinite(h))
        throw InputError("the voxel size must be a positive number of mm", "give --voxel-size, e.g. 0.5");
    if (!(params.noise >= 0) || !std::isfinite(params.noise))
        throw InputError("the noise amplitude must be zero or positive (voxel widths)", "give --noise, e.g. 0.3");
    Vec3 lo, hi;
    shape.bounds(lo, hi);
    // One voxel of margin beyond the noise reach keeps the label off the box edge.
    const double margin = (1.0 + params.noise) * h;
    openvdb::CoordBBox box;
    for (int k = 0; k < 3; ++k) {
        box.min()[k] = static_cast<int32_t>(std::floor((lo[k] - margin) / h));
        box.max()[k] = static_cast<int32_t>(std::ceil((hi[k] + margin) / h));
        if (box.max()[k] - box.min()[k] > 2048)
            throw InputError("a voxel size of " + std::to_string(h) + " mm gives more than 2048 voxels per side",
                             "choose a larger --voxel-size");
    }

    auto grid = openvdb::FloatGrid::create(0.0f);
    // Voxel i spans [i h, (i + 1) h]: its centre is at (i + 1/2) h, so shape
    // boundaries at round millimetres never fall on voxel centres.
    auto transform = openvdb::math::Transform::createLinearTransform(h);
    transform->postTranslate(openvdb::Vec3d(0.5 * h));
    grid->setTransform(transform);
    grid->setName("label");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);

    using Leaf = openvdb::FloatTree::LeafNodeType;
    const int D = Leaf::DIM;
    const openvdb::Coord first = box.min() & ~(D - 1);
    const openvdb::Coord blocks = ((box.max() - first) >> 3) + openvdb::Coord(1);
    std::mutex insert;
    auto& tree = grid->tree();
    // Each leaf-sized block is evaluated independently; wholly inside blocks
    // become active tiles, as a pruned segmentation would hold them.
    tbb::parallel_for(tbb::blocked_range3d<int>(0, blocks.x(), 0, blocks.y(), 0, blocks.z()),
                      [&](const tbb::blocked_range3d<int>& r) {
        for (int bi = r.pages().begin(); bi != r.pages().end(); ++bi)
            for (int bj = r.rows().begin(); bj != r.rows().end(); ++bj)
                for (int bk = r.cols().begin(); bk != r.cols().end(); ++bk) {
                    const openvdb::Coord origin = first + openvdb::Coord(bi * D, bj * D, bk * D);
                    auto leaf = std::make_unique<Leaf>(origin, 0.0f, false);
                    int inside = 0;
                    for (openvdb::Index n = 0; n < Leaf::SIZE; ++n) {
                        const openvdb::Coord c = leaf->offsetToGlobalCoord(n);
                        double s = shape.sdf({(c.x() + 0.5) * h, (c.y() + 0.5) * h, (c.z() + 0.5) * h});
                        if (params.noise > 0) s += params.noise * h * voxel_noise(c.x(), c.y(), c.z(), params.seed);
                        if (s < 0) {
                            leaf->setValueOn(n, 1.0f);
                            ++inside;
                        }
                    }
                    if (inside == 0) continue;
                    std::lock_guard<std::mutex> lock(insert);
                    if (inside == static_cast<int>(Leaf::SIZE)) tree.addTile(1, origin, 1.0f, true);
                    else tree.addLeaf(leaf.release());
                }
    });
    return grid;
}

} // namespace scalemesh
