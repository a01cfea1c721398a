// floor_warnings: one sentence per floor the volume mesh misses, with its
// figure, and none when it misses none.

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

} // namespace
} // namespace scalemesh
