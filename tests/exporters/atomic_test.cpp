#include "core/errors.h"
#include "exporters/surface_writers.h"
#include "importers/stl_importer.h"
#include "test_support.h"

namespace scalemesh::test {
namespace {

class AtomicWrite : public ScratchDir {};

const char* const kExtensions[] = {".stl", ".vtk", ".msh"};

TEST_F(AtomicWrite, MissingDirectoryIsIoErrorNamingThePath)
{
    for (const char* extension : kExtensions) {
        const auto path = dir / "absent" / (std::string("s") + extension);
        try {
            write_surface(octahedron(1), {}, path);
            ADD_FAILURE() << "no error writing " << path;
        } catch (const IoError& e) {
            EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
        }
        EXPECT_FALSE(std::filesystem::exists(dir / "absent"));
    }
    EXPECT_TRUE(entries().empty());
}

TEST_F(AtomicWrite, BadInputLeavesNoFileAndKeepsTheOldOne)
{
    const SurfaceMesh mesh = octahedron(1);
    for (const char* extension : kExtensions) {
        const auto path = dir / (std::string("s") + extension);
        write_text(path, "previous contents");
        EXPECT_THROW(write_surface(mesh, {VertexField{"D", {1, 2, 3}}}, path), InputError);

        SurfaceMesh bad_patches = mesh;
        bad_patches.triangle_patch = {0, 1};
        EXPECT_THROW(write_surface(bad_patches, {}, path), InputError);
        bad_patches.triangle_patch.assign(mesh.triangles.size(), -1);
        EXPECT_THROW(write_surface(bad_patches, {}, path), InputError);
        SurfaceMesh bad_index = mesh;
        bad_index.triangles[3][1] = 6;
        EXPECT_THROW(write_surface(bad_index, {}, path), InputError);

        EXPECT_EQ(read_text(path), "previous contents");
        std::filesystem::remove(path);
        EXPECT_TRUE(entries().empty()) << extension;
    }
}

TEST_F(AtomicWrite, FailureAfterWritingRemovesTheTemporaryFile)
{
    // A directory where the file should go: the writer finishes, the final
    // rename fails, and the temporary file must go.
    for (const char* extension : kExtensions) {
        const auto path = dir / (std::string("blocked") + extension);
        std::filesystem::create_directory(path);
        EXPECT_THROW(write_surface(octahedron(1), {VertexField{"D", std::vector<double>(6, 2.0)}}, path), IoError);
        EXPECT_EQ(entries(), std::vector<std::string>{path.filename().string()});
        std::filesystem::remove(path);
    }
}

TEST_F(AtomicWrite, OverwritesACompleteFile)
{
    write_surface(octahedron(1), {}, dir / "s.stl");
    write_surface(icosphere(1, 1), {}, dir / "s.stl");
    EXPECT_EQ(read_stl(dir / "s.stl").triangles.size(), 80u);
    EXPECT_EQ(entries(), std::vector<std::string>{"s.stl"});
}

TEST_F(AtomicWrite, UnknownExtensionNamesTheValidOnes)
{
    try {
        write_surface(octahedron(1), {}, dir / "s.obj");
        ADD_FAILURE() << "no error for .obj";
    } catch (const InputError& e) {
        const std::string message = e.what();
        for (const char* extension : kExtensions)
            EXPECT_NE(message.find(extension), std::string::npos) << message;
    }
    EXPECT_THROW(write_surface(octahedron(1), {}, dir / "no_extension"), InputError);
    EXPECT_TRUE(entries().empty());
}

} // namespace
} // namespace scalemesh::test
