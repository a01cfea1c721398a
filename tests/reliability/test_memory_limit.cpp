// Issue 10, item 4: resource limits. Before the heavy stages the pipeline
// estimates its peak memory (pipeline/memory_estimate.h) and stops with an
// InputError when it exceeds --max-memory, instead of being killed; the
// estimate is checked against the peak resident memory measured in the run.

#include "hostile_support.h"
#include "pipeline/memory_estimate.h"
#include "support/comma_locale.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace scalemesh {
namespace {

// A plate one voxel thick (or `voxels`) and 16 mm wide whose feature size
// is the thickness everywhere: a medium case (about 60,000 volume points
// one voxel thick).
void write_plate(const TempDir& dir, int voxels = 1)
{
    write_label_mha(dir.path / "image.mha", {voxels, 32, 32}, 0.5, [](int, int, int) { return true; });
    write_case(dir.path, "[input]\nfile = \"image.mha\"\n");
}

// The host's LC_NUMERIC does not change how a size reads. Under a locale
// whose decimal separator is a comma (support/comma_locale.h: glibc's de_DE
// source, which the locales package ships), "1.5 GiB" is still 1.5 GiB,
// and "1,5G" is no size.
TEST(MemoryLimit, SizesParseAlikeUnderACommaLocale)
{
    const CommaNumericLocale comma;
    ASSERT_EQ(comma.failure(), "");
    EXPECT_EQ(parse_memory_size("1.5 GiB", "--max-memory"), 3LL << 29);
    EXPECT_THROW(parse_memory_size("1,5G", "--max-memory"), InputError);
}

TEST(MemoryLimit, SizesParse)
{
    EXPECT_EQ(parse_memory_size("8G", "--max-memory"), 8LL << 30);
    EXPECT_EQ(parse_memory_size("512M", "--max-memory"), 512LL << 20);
    EXPECT_EQ(parse_memory_size("1.5 GiB", "--max-memory"), 3LL << 29);
    EXPECT_EQ(parse_memory_size("300mb", "--max-memory"), 300LL << 20);
    EXPECT_EQ(parse_memory_size(" +8G", "--max-memory"), 8LL << 30); // as std::stod read it
    EXPECT_EQ(parse_memory_size("2000000000", "--max-memory"), 2000000000LL);
    for (const std::string bad : {"", "lots", "8X", "-1G", "0", "nanG", "1e30G", "0.5", "1000K"})
        EXPECT_THROW(parse_memory_size(bad, "--max-memory"), InputError) << bad;
    // A forgotten unit is named, not taken as no limit (0.5 bytes rounds to 0).
    try {
        parse_memory_size("0.5", "--max-memory");
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("--max-memory '0.5' is 0 bytes, less than any run needs. Hint: a bare "
                                             "number is bytes: give a unit, e.g. 8G or 512M"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_GT(physical_memory(), 0);
}

TEST(MemoryLimit, TinyBoundIsRefusedBeforeAnyOutput)
{
    const TempDir dir;
    write_plate(dir);
    const CommandResult r = run_case_limited(dir.path, 120, {"--max-memory", "50M"});
    expect_refused(r, dir.path, {"image.mha"});
    EXPECT_NE(r.err.find("would need about"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("more than the 50 MiB allowed"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("voxel size"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("L_max"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("region of interest"), std::string::npos) << r.err;
}

TEST(MemoryLimit, BoundBelowTheVolumeStageIsRefusedBeforeIt)
{
    // Enough for the surface stages, not for the volume mesh.
    const TempDir dir;
    write_plate(dir);
    const CommandResult r = run_case_limited(dir.path, 120, {"--max-memory", "150M"});
    expect_refused(r, dir.path, {"image.mha"});
    EXPECT_NE(r.err.find("volume mesh points for M = 7 layers"), std::string::npos) << r.err;
}

// Sizes far beyond any machine: the estimate is still a number with its
// unit (not an overflowed count), and the hint points the right way.
TEST(MemoryLimit, AnAbsurdlyFineSizingIsRefusedInPlainFigures)
{
    const TempDir dir;
    write_plate(dir);
    write_case(dir.path, "[input]\nfile = \"image.mha\"\n[sizing]\nL_min = \"1e-5 mm\"\nL_max = \"1e-5 mm\"\n");
    const CommandResult r = run_case_limited(dir.path, 120);
    expect_refused(r, dir.path, {"image.mha"});
    EXPECT_EQ(r.err.find("-9223372036854775808"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(" TiB of memory (about "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("a larger [sizing] L_max or L_min"), std::string::npos) << r.err;
}

TEST(MemoryLimit, UnreadableBoundIsRefused)
{
    const TempDir dir;
    write_plate(dir);
    expect_refused(run_case_limited(dir.path, 120, {"--max-memory", "plenty"}), dir.path, {"image.mha"});
}

// Two voxels thick: one voxel's plate gives its prism layers up and is
// meshed twice (36 s against 8 s), so the estimates are no longer measured
// on a run that falls back to the Delaunay layers.
TEST(MemoryLimit, EstimatesWithinAFactorOfTwoOfTheMeasuredPeak)
{
    const TempDir dir;
    write_plate(dir, 2);
    const CommandResult r = run_case_limited(dir.path, 120);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json memory = nlohmann::json::parse(std::ifstream(dir.path / "report.json"))["memory"];
    const double measured = memory["measured_peak_bytes"];
    EXPECT_EQ(memory["bound_bytes"].get<int64_t>(), physical_memory());
    for (const std::string key : {"estimated_peak_bytes_before_remeshing", "estimated_peak_bytes_before_volume"}) {
        const double estimate = memory[key];
        EXPECT_GT(estimate, measured / 2) << key;
        EXPECT_LT(estimate, measured * 2) << key;
    }
    // Each stage's memory, in the order of the report's stages: its peak at
    // least what it left resident, the run's peak the largest of them.
    const nlohmann::json report = nlohmann::json::parse(std::ifstream(dir.path / "report.json"));
    const nlohmann::json& stages = memory["stages"];
    ASSERT_EQ(stages.size(), report["stages"].size());
    int64_t largest = 0;
    for (size_t i = 0; i < stages.size(); ++i) {
        EXPECT_EQ(stages[i]["stage"], report["stages"][i]["stage"]);
        const int64_t peak = stages[i]["peak_bytes"], resident = stages[i]["resident_after_bytes"];
        EXPECT_GT(resident, 0) << stages[i];
        EXPECT_GE(peak, resident) << stages[i];
        EXPECT_GT(stages[i]["resident_after_bytes_per_tet"].get<double>(), 0) << stages[i];
        largest = std::max(largest, peak);
    }
    EXPECT_GE(measured, double(largest));
}

// The peak resident set, reset: a 256 MiB block touched and freed leaves
// the peak at least 256 MiB above what is resident; after the reset the peak
// is what is resident again, and getrusage's peak (the report's
// measured_peak_bytes) with it.
TEST(MemoryLimit, APeakResetForgetsWhatWasFreed)
{
    const auto before = resident_memory();
    ASSERT_TRUE(before);
    const size_t size = size_t(256) << 20;
    {
        std::vector<char> block(size);
        volatile char* page = block.data(); // every page written, not optimised away
        for (size_t i = 0; i < size; i += 4096) page[i] = 1;
    }
    const auto held = resident_memory();
    ASSERT_TRUE(held);
    EXPECT_GE(held->peak_bytes, before->now_bytes + int64_t(size) * 9 / 10);
    ASSERT_TRUE(reset_peak_resident_memory());
    const auto after = resident_memory();
    ASSERT_TRUE(after);
    EXPECT_LT(after->peak_bytes, held->peak_bytes - int64_t(size) / 2);
    EXPECT_LT(peak_resident_memory(), held->peak_bytes - int64_t(size) / 2);
}

} // namespace
} // namespace scalemesh
