// libFuzzer target: Wavefront OBJ through read_surface.

#include "fuzz/fuzz_file.h"
#include "importers/surface_importer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    scalemesh::fuzz::read_as_file(data, size, "input.obj",
                                  [](const std::filesystem::path& path) { scalemesh::read_surface(path); });
    return 0;
}
