// libFuzzer target: OpenVDB files through read_vdb.

#include "fuzz/fuzz_file.h"
#include "importers/vdb_importer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    scalemesh::fuzz::read_as_file(data, size, "input.vdb",
                                  [](const std::filesystem::path& path) { scalemesh::read_vdb(path); });
    return 0;
}
