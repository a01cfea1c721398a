// The polyMesh writer formats its files in parallel blocks: the bytes must not
// depend on the number of threads, and the ASCII and binary files must hold
// the same numbers. The box is large enough to span several blocks of cells
// and of points.

#include "core/tet_mesh.h"
#include "exporters/polymesh_writer.h"
#include "openfoam_support.h"
#include "tet_meshes.h"

#include "support/temp_dir.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <charconv>
#include <cstring>

namespace scalemesh {
namespace {

constexpr const char* kFiles[] = {"points", "faces", "owner", "neighbour", "boundary"};

const TetMesh& big_box()
{
    // 6 * 30^3 = 162,000 cells (about 10 blocks of cells), 29,791 points.
    static const TetMesh mesh = box_of_cubes(30, 30, 30);
    return mesh;
}

std::filesystem::path write_with_threads(const std::filesystem::path& case_dir, int threads, bool binary)
{
    tbb::task_arena arena(threads);
    arena.execute([&] {
        EXPECT_EQ(tbb::this_task_arena::max_concurrency(), threads);
        write_polymesh(big_box(), case_dir, {.binary = binary, .scale = 1e-3, .patch_types = {"wall", "patch", "patch"}});
    });
    return case_dir / "constant" / "polyMesh";
}

// The lists of a polyMesh, ASCII or binary, read back as numbers.
struct Lists {
    std::vector<double> points; // x, y, z per point
    std::vector<int64_t> faces; // the point labels, 3 per face
    std::vector<int64_t> owner, neighbour;
};

class ListReader {
public:
    explicit ListReader(const std::filesystem::path& file) : text_(read_text(file))
    {
        binary_ = text_.find("format      binary;") != std::string::npos;
        at_ = text_.find("}\n");
        EXPECT_NE(at_, std::string::npos) << file;
        at_ += 2;
    }

    // The next number in ASCII text, skipping blanks and parentheses.
    template <typename Number>
    Number number()
    {
        while (at_ < text_.size() && std::strchr(" \n()", text_[at_])) ++at_;
        Number value{};
        const auto r = std::from_chars(text_.data() + at_, text_.data() + text_.size(), value);
        EXPECT_EQ(r.ec, std::errc()) << "at byte " << at_;
        at_ = static_cast<size_t>(r.ptr - text_.data());
        return value;
    }

    // A list of `per` numbers per entry; the list's size counts entries.
    // ASCII faces carry their own size (3) before each entry.
    template <typename Stored, typename Number>
    std::vector<Number> list(int per, bool sized_entries = false)
    {
        const auto n = number<int64_t>();
        std::vector<Number> values;
        if (binary_) {
            at_ = text_.find('(', at_) + 1;
            for (int64_t i = 0; i < n * per; ++i) {
                Stored v;
                std::memcpy(&v, text_.data() + at_, sizeof v);
                at_ += sizeof v;
                values.push_back(static_cast<Number>(v));
            }
            EXPECT_EQ(text_[at_], ')');
            ++at_;
            return values;
        }
        for (int64_t i = 0; i < n; ++i) {
            if (sized_entries) {
                EXPECT_EQ(number<int64_t>(), per);
            }
            for (int k = 0; k < per; ++k) values.push_back(number<Number>());
        }
        return values;
    }

    bool binary() const { return binary_; }

private:
    std::string text_;
    bool binary_ = false;
    size_t at_ = 0;
};

Lists read_lists(const std::filesystem::path& poly)
{
    Lists lists;
    lists.points = ListReader(poly / "points").list<double, double>(3);
    ListReader faces(poly / "faces");
    if (faces.binary()) {
        const auto offsets = faces.list<int32_t, int64_t>(1);
        for (size_t f = 0; f < offsets.size(); ++f) EXPECT_EQ(offsets[f], 3 * static_cast<int64_t>(f));
        lists.faces = faces.list<int32_t, int64_t>(1);
    } else {
        lists.faces = faces.list<int32_t, int64_t>(3, true);
    }
    lists.owner = ListReader(poly / "owner").list<int32_t, int64_t>(1);
    lists.neighbour = ListReader(poly / "neighbour").list<int32_t, int64_t>(1);
    return lists;
}

TEST(PolyMeshThreads, OneAndTwoThreadsWriteTheSameBytes)
{
    for (bool binary : {false, true}) {
        const TempDir dir;
        const auto one = write_with_threads(dir.path / "one", 1, binary);
        const auto two = write_with_threads(dir.path / "two", 2, binary);
        for (const char* name : kFiles) {
            const std::string a = read_text(one / name), b = read_text(two / name);
            EXPECT_FALSE(a.empty()) << name;
            EXPECT_TRUE(a == b) << name << (binary ? " (binary)" : " (ascii)") << " differs between 1 and 2 threads";
        }
    }
}

TEST(PolyMeshThreads, AsciiAndBinaryHoldTheSameMesh)
{
    const TempDir dir;
    const Lists ascii = read_lists(write_with_threads(dir.path / "ascii", 2, false));
    const Lists binary = read_lists(write_with_threads(dir.path / "binary", 2, true));
    const TetMesh& mesh = big_box();
    ASSERT_EQ(ascii.points.size(), 3 * mesh.points.size());
    // Shortest round-trip text gives back the very doubles.
    EXPECT_TRUE(ascii.points == binary.points);
    for (size_t i = 0; i < mesh.points.size(); ++i)
        for (int k = 0; k < 3; ++k) ASSERT_EQ(ascii.points[3 * i + k], mesh.points[i][k] * 1e-3);
    EXPECT_TRUE(ascii.faces == binary.faces);
    EXPECT_TRUE(ascii.owner == binary.owner);
    EXPECT_TRUE(ascii.neighbour == binary.neighbour);
    // Every cell face once: 4 per cell, internal ones twice.
    EXPECT_EQ(ascii.owner.size() + ascii.neighbour.size(), 4 * mesh.tets.size());
    EXPECT_EQ(ascii.faces.size(), 3 * ascii.owner.size());
    // The patches are the same; only the format line differs.
    std::string boundary = read_text(dir.path / "binary" / "constant" / "polyMesh" / "boundary");
    const size_t format = boundary.find("format      binary;");
    ASSERT_NE(format, std::string::npos);
    boundary.replace(format, 19, "format      ascii;");
    EXPECT_EQ(read_text(dir.path / "ascii" / "constant" / "polyMesh" / "boundary"), boundary);
}

TEST(PolyMeshThreads, BigBoxFollowsTheOrderingRules)
{
    const TempDir dir;
    const Lists lists = read_lists(write_with_threads(dir.path, 2, true));
    const auto& owner = lists.owner;
    const auto& neighbour = lists.neighbour;
    for (size_t f = 0; f < neighbour.size(); ++f) {
        ASSERT_LT(owner[f], neighbour[f]) << "face " << f;
        if (f > 0) {
            ASSERT_TRUE(owner[f - 1] < owner[f] || (owner[f - 1] == owner[f] && neighbour[f - 1] < neighbour[f]))
                << "face " << f << " is not in upper-triangular order";
        }
    }
    if (openfoam_available()) {
        const CheckMeshFigures check = check_mesh(dir.path);
        EXPECT_TRUE(check.ok) << check.log;
        EXPECT_EQ(check.cells, static_cast<long>(big_box().tets.size()));
    }
}

} // namespace
} // namespace scalemesh
