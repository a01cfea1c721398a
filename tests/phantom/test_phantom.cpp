// Phantom label images: binary values, the voxel size in the transform, the
// analytic volume, determinism, and refusal of impossible parameters.

#include "core/errors.h"
#include "phantom/phantom.h"

#include <gtest/gtest.h>

#include <cmath>

namespace scalemesh {
namespace {

class Phantom : public ::testing::TestWithParam<std::string> {};

TEST_P(Phantom, IsABinaryLabelWhoseVoxelsMatchTheShape)
{
    const double h = 0.5;
    const auto shape = make_shape(GetParam(), h);
    const auto grid = voxelize(*shape, {.voxel_size = h});
    EXPECT_EQ(grid->getName(), "label");
    EXPECT_DOUBLE_EQ(grid->voxelSize().x(), h);
    EXPECT_DOUBLE_EQ(grid->voxelSize().z(), h);
    EXPECT_EQ(grid->background(), 0.0f);
    // Every active value is 1 and lies inside the shape; the voxels just
    // outside the active set are outside it.
    int64_t checked = 0;
    for (auto it = grid->cbeginValueOn(); it; ++it) {
        EXPECT_EQ(*it, 1.0f);
        if (it.isVoxelValue()) {
            const auto w = grid->indexToWorld(it.getCoord());
            ASSERT_LT(shape->sdf({w.x(), w.y(), w.z()}), 0.0);
            ++checked;
        }
    }
    EXPECT_GT(checked, 0);
    const double volume = static_cast<double>(grid->activeVoxelCount()) * h * h * h;
    if (std::isfinite(shape->volume())) {
        EXPECT_NEAR(volume, shape->volume(), 0.03 * shape->volume());
    }
}

INSTANTIATE_TEST_SUITE_P(AllShapes, Phantom, ::testing::ValuesIn(phantom_names()),
                         [](const auto& info) { return info.param; });

TEST(Phantom, InteriorBlocksAreStoredAsTiles)
{
    const auto grid = voxelize(*make_shape("sphere", 0.25), {.voxel_size = 0.25});
    EXPECT_GT(grid->tree().activeTileCount(), 0u);
}

TEST(Phantom, NoiseIsSeededAndMovesOnlyVoxelsNearTheSurface)
{
    const auto shape = make_shape("torus", 0.5);
    const auto clean = voxelize(*shape, {.voxel_size = 0.5});
    const auto a = voxelize(*shape, {.voxel_size = 0.5, .noise = 0.5, .seed = 7});
    const auto b = voxelize(*shape, {.voxel_size = 0.5, .noise = 0.5, .seed = 7});
    const auto c = voxelize(*shape, {.voxel_size = 0.5, .noise = 0.5, .seed = 8});
    EXPECT_EQ(a->activeVoxelCount(), b->activeVoxelCount());
    EXPECT_NE(a->activeVoxelCount(), clean->activeVoxelCount());
    int differing = 0;
    for (auto it = a->cbeginValueOn(); it; ++it) {
        if (!it.isVoxelValue()) continue;
        const auto p = it.getCoord();
        EXPECT_TRUE(b->tree().isValueOn(p));
        if (!c->tree().isValueOn(p)) ++differing;
        // Noise of half a voxel only flips voxels within half a voxel of the surface.
        const auto w = a->indexToWorld(p);
        EXPECT_LT(shape->sdf({w.x(), w.y(), w.z()}), 0.25 + 1e-12);
    }
    EXPECT_GT(differing, 0);
}

TEST(Phantom, TwinTubesKeepAGapOfAtLeastOneOutsideVoxel)
{
    for (double h : {0.25, 0.5, 0.7}) {
        const auto grid = voxelize(*make_shape("twin_tubes", h), {.voxel_size = h});
        // No inside voxel left of the mid-plane has an inside face neighbour
        // right of it.
        int64_t left = 0;
        for (auto it = grid->cbeginValueOn(); it; ++it) {
            if (!it.isVoxelValue() || grid->indexToWorld(it.getCoord()).x() > 0) continue;
            ++left;
            const auto right = it.getCoord().offsetBy(1, 0, 0);
            if (grid->indexToWorld(right).x() > 0) {
                EXPECT_FALSE(grid->tree().isValueOn(right)) << h;
            }
        }
        EXPECT_GT(left, 0);
    }
}

TEST(Phantom, RefusesUnknownShapesAndImpossibleVoxelSizes)
{
    EXPECT_THROW(make_shape("cube", 1.0), InputError);
    const auto shape = make_shape("sphere", 1.0);
    EXPECT_THROW(voxelize(*shape, {.voxel_size = 0}), InputError);
    EXPECT_THROW(voxelize(*shape, {.voxel_size = -1}), InputError);
    EXPECT_THROW(voxelize(*shape, {.voxel_size = std::nan("")}), InputError);
    EXPECT_THROW(voxelize(*shape, {.voxel_size = 0.001}), InputError);
    EXPECT_THROW(voxelize(*shape, {.voxel_size = 0.5, .noise = -1}), InputError);
}

} // namespace
} // namespace scalemesh
