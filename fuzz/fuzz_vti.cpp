// libFuzzer target: VTK XML ImageData through read_image.

#include "fuzz/fuzz_file.h"
#include "importers/image_importer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    scalemesh::fuzz::read_as_file(data, size, "input.vti",
                                  [](const std::filesystem::path& path) { scalemesh::read_image(path); });
    return 0;
}
