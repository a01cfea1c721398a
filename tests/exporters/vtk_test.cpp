#include "core/errors.h"
#include "exporters/surface_writers.h"
#include "test_support.h"

#include <charconv>
#include <sstream>

namespace scalemesh::test {
namespace {

// A reader for the subset of legacy VTK that write_surface produces, strict
// enough to fail on any miscount.
class VtkTokens {
public:
    explicit VtkTokens(const std::string& text) : stream_(text) {}

    std::string line()
    {
        std::string l;
        std::getline(stream_ >> std::ws, l);
        return l;
    }
    std::string word()
    {
        std::string w;
        stream_ >> w;
        return w;
    }
    int64_t integer()
    {
        const std::string w = word();
        int64_t value = 0;
        const auto [end, error] = std::from_chars(w.data(), w.data() + w.size(), value);
        EXPECT_TRUE(error == std::errc() && end == w.data() + w.size()) << "'" << w << "' is not an integer";
        return value;
    }
    double number()
    {
        const std::string w = word();
        double value = 0;
        const auto [end, error] = std::from_chars(w.data(), w.data() + w.size(), value);
        EXPECT_TRUE(error == std::errc() && end == w.data() + w.size()) << "'" << w << "' is not a number";
        return value;
    }
    bool done() { return (stream_ >> std::ws).eof(); }

private:
    std::istringstream stream_;
};

class Vtk : public ScratchDir {};

TEST_F(Vtk, WellFormedPolydataWithPatchesAndFields)
{
    SurfaceMesh mesh = translated(uv_sphere(4, 12, 7), {0.1, 1e-7, -250});
    for (size_t f = 0; f < mesh.triangles.size(); ++f) mesh.triangle_patch.push_back(f % 5 == 0 ? 2 : 0);
    std::vector<VertexField> fields(3);
    fields[0].name = "D";
    fields[1].name = "d out";
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        fields[0].values.push_back(0.1 * double(i) + 1e-300);
        fields[1].values.push_back(-1.0 / 3.0 * double(i));
        fields[2].values.push_back(mesh.points[i].z);
    }
    write_surface(mesh, fields, dir / "s.vtk");

    VtkTokens vtk(read_text(dir / "s.vtk"));
    EXPECT_EQ(vtk.line(), "# vtk DataFile Version 3.0");
    vtk.line(); // title
    EXPECT_EQ(vtk.line(), "ASCII");
    EXPECT_EQ(vtk.line(), "DATASET POLYDATA");

    EXPECT_EQ(vtk.word(), "POINTS");
    ASSERT_EQ(vtk.integer(), int64_t(mesh.points.size()));
    EXPECT_EQ(vtk.word(), "double");
    for (const Vec3& p : mesh.points)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(vtk.number(), p[c]); // shortest round-trip text: exact

    EXPECT_EQ(vtk.word(), "POLYGONS");
    ASSERT_EQ(vtk.integer(), int64_t(mesh.triangles.size()));
    EXPECT_EQ(vtk.integer(), 4 * int64_t(mesh.triangles.size()));
    for (const Triangle& t : mesh.triangles) {
        EXPECT_EQ(vtk.integer(), 3);
        for (int32_t v : t) EXPECT_EQ(vtk.integer(), v);
    }

    EXPECT_EQ(vtk.word(), "CELL_DATA");
    EXPECT_EQ(vtk.integer(), int64_t(mesh.triangles.size()));
    EXPECT_EQ(vtk.line(), "SCALARS patch int 1");
    EXPECT_EQ(vtk.line(), "LOOKUP_TABLE default");
    for (int32_t patch : mesh.triangle_patch) EXPECT_EQ(vtk.integer(), patch);

    EXPECT_EQ(vtk.word(), "POINT_DATA");
    EXPECT_EQ(vtk.integer(), int64_t(mesh.points.size()));
    const std::vector<std::string> names = {"D", "d_out", "field_2"}; // VTK names are single tokens
    for (size_t k = 0; k < fields.size(); ++k) {
        EXPECT_EQ(vtk.line(), "SCALARS " + names[k] + " double 1");
        EXPECT_EQ(vtk.line(), "LOOKUP_TABLE default");
        for (double value : fields[k].values) EXPECT_EQ(vtk.number(), value);
    }
    EXPECT_TRUE(vtk.done());
}

TEST_F(Vtk, NoPatchesNoFieldsMeansNoDataSections)
{
    write_surface(octahedron(1), {}, dir / "plain.vtk");
    const std::string text = read_text(dir / "plain.vtk");
    EXPECT_NE(text.find("POLYGONS 8 32\n"), std::string::npos);
    EXPECT_EQ(text.find("CELL_DATA"), std::string::npos);
    EXPECT_EQ(text.find("POINT_DATA"), std::string::npos);
}

} // namespace
} // namespace scalemesh::test
