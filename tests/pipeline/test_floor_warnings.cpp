// floor_warnings and openfoam_check_warnings: one sentence per floor the
// mesh misses, with its figure, and none when it misses none.

#include "pipeline/run_case.h"

#include <gtest/gtest.h>

#include <string>

namespace scalemesh {
namespace {

TEST(FloorWarnings, AFaceBeyondCheckMeshsSevereNonOrthogonalityIsWarnedOf)
{
    CaseConfig config;
    PipelineRun run;
    EXPECT_TRUE(floor_warnings(config, run).empty()); // no volume mesh, nothing to warn of

    run.volume.emplace();
    run.volume->after_slivers.min_aspect_ratio = 0.3;
    run.volume->after_slivers.min_dihedral_deg = 20;
    run.volume->max_non_orthogonality_deg = 69.99;
    EXPECT_TRUE(floor_warnings(config, run).empty());

    run.volume->max_non_orthogonality_deg = 70.14;
    const std::vector<std::string> warnings = floor_warnings(config, run);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("70.14 degrees off orthogonal"), std::string::npos) << warnings[0];
    EXPECT_NE(warnings[0].find("checkMesh"), std::string::npos) << warnings[0];
}

// With layer prisms written as cells (layers = "prisms"), the cell floors
// are left out of floor_warnings and judged on the tet cells instead,
// whose sentences say so.
TEST(FloorWarnings, TheCellFloorsCanBeJudgedOnTheCellsWritten)
{
    CaseConfig config;
    PipelineRun run;
    run.volume.emplace();
    run.volume->after_slivers.min_aspect_ratio = 0.01; // a layer prism's own flat tets
    run.volume->after_slivers.min_dihedral_deg = 2;
    run.volume->max_non_orthogonality_deg = 85;
    EXPECT_EQ(floor_warnings(config, run).size(), 3u);
    EXPECT_TRUE(floor_warnings(config, run, /*cells_later=*/true).empty());

    EXPECT_TRUE(cell_floor_warnings(config, {.min_aspect_ratio = 0.2, .min_dihedral_deg = 11,
                                             .max_non_orthogonality_deg = 69, .what = "tet cell"})
                    .empty());
    const std::vector<std::string> warnings = cell_floor_warnings(
        config, {.min_aspect_ratio = 0.2, .min_dihedral_deg = 7.34, .max_non_orthogonality_deg = 69, .what = "tet cell"});
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("of a tet cell is 7.34 degrees"), std::string::npos) << warnings[0];
}

// Faces of the OpenFOAM cells that checkMesh would fail (left on single
// tets, nothing to split back) are warned of; faces beyond the split-back
// margins alone are not.
TEST(FloorWarnings, FacesCheckMeshWouldFailAreWarnedOf)
{
    OpenFoamCellChecks checks;
    checks.max_skewness = 3.9;
    checks.skew_faces = 2; // beyond the 3.8 margin, within checkMesh's 4
    checks.flat_pyramids = 1;
    EXPECT_TRUE(openfoam_check_warnings(checks).empty());

    checks.max_skewness = 4.37;
    checks.checkmesh_failures = 3;
    const std::vector<std::string> warnings = openfoam_check_warnings(checks);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("3 faces of the OpenFOAM cells would fail checkMesh"), std::string::npos) << warnings[0];
    EXPECT_NE(warnings[0].find("worst skewness 4.37"), std::string::npos) << warnings[0];
}

// Parameters that make no layer at all pass the coverage floor vacuously
// (no node is owed a layer): each is warned of, so that --strict fails it.
TEST(FloorWarnings, ParametersThatMakeNoLayersAreWarnedOf)
{
    CaseConfig config;
    PipelineRun run;
    run.volume.emplace();
    run.volume->after_slivers.min_aspect_ratio = 0.3;
    run.volume->after_slivers.min_dihedral_deg = 20;
    LayerAccount& a = run.volume->layers;
    a.wall_nodes = 120;
    a.layermaking = 3;
    a.eligible_nodes = a.eligible_full = 120;
    EXPECT_TRUE(floor_warnings(config, run).empty());

    config.M = 1.5;
    a.layermaking = 0;
    std::vector<std::string> warnings = floor_warnings(config, run);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("M = 1.5 makes no layers along the wall"), std::string::npos) << warnings[0];

    config.M = 7;
    a.layermaking = 3;
    a.eligible_nodes = a.eligible_full = 0;
    run.L_min = 100;
    warnings = floor_warnings(config, run);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("no wall node has a local diameter D of at least L_min = 100 mm"), std::string::npos)
        << warnings[0];
}

} // namespace
} // namespace scalemesh
