// libFuzzer target: NIfTI-1 through read_image, as .nii.gz when the input
// starts with gzip's magic number and as .nii otherwise, so that both the
// plain and the compressed paths are reached.

#include "fuzz/fuzz_file.h"
#include "importers/image_importer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const bool gzip = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
    scalemesh::fuzz::read_as_file(data, size, gzip ? "input.nii.gz" : "input.nii",
                                  [](const std::filesystem::path& path) { scalemesh::read_image(path); });
    return 0;
}
