// libFuzzer target: VTK XML PolyData, every encoding (the seeds hold ascii,
// inline binary and appended raw and base64, plain and zlib), through
// read_vtp_labelled, so that the face labels are read too.

#include "fuzz/fuzz_file.h"
#include "importers/surface_importer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    scalemesh::fuzz::read_as_file(data, size, "input.vtp",
                                  [](const std::filesystem::path& path) { scalemesh::read_vtp_labelled(path); });
    return 0;
}
