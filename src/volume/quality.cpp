#include "volume/quality.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>

namespace scalemesh {

double tet_aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    const double volume = tet_volume6(a, b, c, d) / 6.0;
    const double area = 0.5 * (norm(cross(b - a, c - a)) + norm(cross(b - a, d - a)) +
                               norm(cross(c - a, d - a)) + norm(cross(c - b, d - b)));
    const double l2 = std::max({norm2(b - a), norm2(c - a), norm2(d - a), norm2(c - b), norm2(d - b), norm2(d - c)});
    if (!(area > 0) || !(l2 > 0)) return 0;
    const double r_in = 3.0 * volume / area;
    return 2.0 * std::sqrt(6.0) * r_in / std::sqrt(l2);
}

double tet_min_dihedral_deg(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    // The dihedral angle at the edge where faces k and l meet is pi minus the
    // angle between their outward normals: cos = -n_k . n_l. The smallest
    // angle has the largest cosine, so one acos per tet is enough.
    if (!(tet_volume6(a, b, c, d) > 0)) return 0;
    const Vec3 v[4] = {a, b, c, d};
    Vec3 normal[4];
    for (int k = 0; k < 4; ++k) {
        const Vec3 &p = v[kTetFaces[k][0]], &q = v[kTetFaces[k][1]], &r = v[kTetFaces[k][2]];
        const Vec3 n = cross(q - p, r - p);
        const double length = norm(n);
        if (!(length > 0)) return 0;
        normal[k] = n / length;
    }
    double largest_cosine = -1.0;
    for (int k = 0; k < 4; ++k)
        for (int l = k + 1; l < 4; ++l) largest_cosine = std::max(largest_cosine, -dot(normal[k], normal[l]));
    return std::acos(std::clamp(largest_cosine, -1.0, 1.0)) * 180.0 / M_PI;
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
            const double q = tet_aspect_ratio(a, bb, c, d);
            p.min_q = std::min(p.min_q, q);
            p.min_dihedral = std::min(p.min_dihedral, tet_min_dihedral_deg(a, bb, c, d));
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
