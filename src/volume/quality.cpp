#include "volume/quality.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>

namespace scalemesh {

namespace {

// Twice the area times the outward unit normal of each face of (a, b, c, d),
// face k as in kTetFaces.
std::array<Vec3, 4> face_normals(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return {cross(c - b, d - b), cross(d - a, c - a), cross(b - a, d - a), cross(c - a, b - a)};
}

// Both measures from one set of face normals, the angle as the cosine
// dihedral_deg takes. with_dihedral false leaves the angle out (the aspect
// ratio alone is what the improvement loops ask).
TetCosineMeasures tet_shape(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, bool with_dihedral)
{
    const double volume6 = tet_volume6(a, b, c, d);
    const std::array<Vec3, 4> normal = face_normals(a, b, c, d);
    const std::array<double, 4> length = {norm(normal[0]), norm(normal[1]), norm(normal[2]), norm(normal[3])};
    const double area = 0.5 * (length[3] + length[2] + length[1] + length[0]);
    const double l2 = std::max({norm2(b - a), norm2(c - a), norm2(d - a), norm2(c - b), norm2(d - b), norm2(d - c)});
    TetCosineMeasures shape{0, kFlatDihedralCosine};
    if (area > 0 && l2 > 0) {
        const double volume = volume6 / 6.0, r_in = 3.0 * volume / area;
        shape.aspect_ratio = 2.0 * std::sqrt(6.0) * r_in / std::sqrt(l2);
    }
    if (!with_dihedral || !(volume6 > 0) || !(length[0] > 0 && length[1] > 0 && length[2] > 0 && length[3] > 0))
        return shape;
    // The dihedral angle at the edge where faces k and l meet is pi minus
    // the angle between their outward normals: cos = -n_k . n_l. The
    // smallest angle has the largest cosine, so one acos per tet is enough.
    Vec3 unit[4];
    for (int k = 0; k < 4; ++k) unit[k] = normal[k] / length[k];
    double largest_cosine = -1.0;
    for (int k = 0; k < 4; ++k)
        for (int l = k + 1; l < 4; ++l) largest_cosine = std::max(largest_cosine, -dot(unit[k], unit[l]));
    shape.dihedral_cosine = std::clamp(largest_cosine, -1.0, 1.0);
    return shape;
}

} // namespace

double dihedral_deg(double dihedral_cosine)
{
    return dihedral_cosine > 1 ? 0.0 : std::acos(dihedral_cosine) * 180.0 / M_PI;
}

double tet_aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return tet_shape(a, b, c, d, false).aspect_ratio;
}

double tet_min_dihedral_deg(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return dihedral_deg(tet_shape(a, b, c, d, true).dihedral_cosine);
}

TetMeasures tet_measures(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    const TetCosineMeasures shape = tet_shape(a, b, c, d, true);
    return {shape.aspect_ratio, dihedral_deg(shape.dihedral_cosine)};
}

TetCosineMeasures tet_cosine_measures(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return tet_shape(a, b, c, d, true);
}

QualityReport quality_report(const TetMesh& mesh)
{
    QualityReport r;
    r.tets = static_cast<int64_t>(mesh.tets.size());
    if (mesh.tets.empty()) return r;
    struct Partial {
        double min_q = 1e300, min_dihedral = 1e300, sum = 0;
        int64_t low = 0, below_0_02 = 0;
        std::array<int64_t, 20> histogram{};
    };
    // Parallel over blocks of tets; the sum is added per block in order of
    // the blocks, so the mean is the same on any number of threads.
    const size_t block = 1 << 14, blocks = (mesh.tets.size() + block - 1) / block;
    std::vector<Partial> partial(blocks);
    tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
        Partial& p = partial[b];
        const size_t end = std::min(mesh.tets.size(), (b + 1) * block);
        for (size_t i = b * block; i < end; ++i) {
            const Tet& t = mesh.tets[i];
            const Vec3 &a = mesh.points[t[0]], &bb = mesh.points[t[1]], &c = mesh.points[t[2]], &d = mesh.points[t[3]];
            const TetCosineMeasures shape = tet_shape(a, bb, c, d, true);
            const double q = shape.aspect_ratio;
            p.min_q = std::min(p.min_q, q);
            p.min_dihedral = std::min(p.min_dihedral, dihedral_deg(shape.dihedral_cosine));
            p.sum += q;
            p.low += q < 0.1;
            p.below_0_02 += q < kQualityFloor;
            ++p.histogram[std::clamp(static_cast<int>(std::floor(q * 20.0)), 0, 19)];
        }
    });
    r.min_aspect_ratio = 1e300;
    r.min_dihedral_deg = 1e300;
    double sum = 0;
    int64_t low = 0;
    for (const Partial& p : partial) {
        r.min_aspect_ratio = std::min(r.min_aspect_ratio, p.min_q);
        r.min_dihedral_deg = std::min(r.min_dihedral_deg, p.min_dihedral);
        sum += p.sum;
        low += p.low;
        r.below_0_02 += p.below_0_02;
        for (int k = 0; k < 20; ++k) r.histogram[k] += p.histogram[k];
    }
    r.mean_aspect_ratio = sum / double(r.tets);
    r.fraction_below_0_1 = double(low) / double(r.tets);
    return r;
}

} // namespace scalemesh
