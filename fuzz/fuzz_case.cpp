// libFuzzer target: the case file scalemesh.toml through parse_case, which
// reads text only (paths in it are resolved, not opened).

#include "core/errors.h"
#include "fuzz/fuzz_file.h"
#include "pipeline/case_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    try {
        scalemesh::parse_case(std::string(scalemesh::fuzz::as_text(data, size)), "case", "scalemesh.toml");
    } catch (const scalemesh::InputError&) {
    } catch (const scalemesh::IoError&) {
    }
    return 0;
}
