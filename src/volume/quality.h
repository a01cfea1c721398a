#pragma once
// Tetrahedron quality measures and the histograms of paper section 3, Fig. 19.

#include "core/tet_mesh.h"

#include <array>
#include <cstdint>
#include <vector>

namespace scalemesh {

// Aspect ratio 2 sqrt(6) r_in / l_max (paper section 3): 1 for a regular
// tet, 0 for a flat one, negative for an inverted one (signed volume).
// r_in = 3 V / (sum of the face areas). Dimensionless.
double tet_aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// Smallest of the six dihedral angles, in degrees (70.53 for a regular tet);
// 0 for a degenerate tet.
double tet_min_dihedral_deg(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// Both measures above from one set of face normals, the same numbers as
// each alone: what the cell passes ask of every tet they try.
struct TetMeasures {
    double aspect_ratio, min_dihedral_deg;
};
TetMeasures tet_measures(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// The same with the smallest dihedral angle as the cosine it is computed
// from: dihedral_deg(dihedral_cosine) is tet_measures' min_dihedral_deg. The
// angle falls as the cosine grows, so the smallest angle of many tets is
// the angle of the largest cosine: one acos for a set of tets.
struct TetCosineMeasures {
    double aspect_ratio;
    double dihedral_cosine; // in [-1, 1]; kFlatDihedralCosine for a flat or inverted tet (angle 0)
};
constexpr double kFlatDihedralCosine = 2;
TetCosineMeasures tet_cosine_measures(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// The angle in degrees of a TetCosineMeasures::dihedral_cosine.
double dihedral_deg(double dihedral_cosine);

// The aspect ratio below which no tet should be left (what below_0_02 counts).
constexpr double kQualityFloor = 0.02;

struct QualityReport {
    int64_t tets = 0;
    double min_aspect_ratio = 0;     // over all tets (dimensionless)
    double mean_aspect_ratio = 0;
    double min_dihedral_deg = 0;     // degrees
    double fraction_below_0_1 = 0;   // tets with aspect ratio < 0.1, fraction of all tets
    int64_t below_0_02 = 0;          // tets with aspect ratio < 0.02
    std::array<int64_t, 20> histogram{}; // aspect ratio counts in [k/20, (k+1)/20), 1 in the last bin
};

// Linear in the number of tets, in parallel (TBB); the same on any number
// of threads. An empty mesh gives a zero report.
QualityReport quality_report(const TetMesh& mesh);

} // namespace scalemesh
