#pragma once
// What every fuzz target shares: the importers read files by path, so each
// input is written to a file with the extension that selects the format, then
// read. scalemesh's InputError and IoError are the refusal bad input must get;
// any other exception escapes, and libFuzzer reports it as a crash, as it does
// a sanitizer report, a timeout or an oversized allocation.

#include "core/errors.h"

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

namespace scalemesh::fuzz {

// One directory per process, so that parallel jobs (-jobs, -fork) do not
// share files; removed when the fuzzer exits.
class ScratchDirectory {
public:
    ScratchDirectory()
        : path_(std::filesystem::temp_directory_path() / ("scalemesh-fuzz-" + std::to_string(::getpid())))
    {
        std::filesystem::create_directories(path_);
    }
    ~ScratchDirectory()
    {
        std::error_code ignored;
        std::filesystem::remove_all(path_, ignored);
    }
    ScratchDirectory(const ScratchDirectory&) = delete;
    ScratchDirectory& operator=(const ScratchDirectory&) = delete;
    const std::filesystem::path& path() const { return path_; }

private:
    std::filesystem::path path_;
};

inline std::string_view as_text(const uint8_t* data, size_t size)
{
    return {reinterpret_cast<const char*>(data), size};
}

// Writes the input to `file_name` in the scratch directory and calls
// read(path), which must either succeed or throw InputError or IoError.
template <typename Read>
void read_as_file(const uint8_t* data, size_t size, const std::string& file_name, const Read& read)
{
    static const ScratchDirectory scratch;
    const std::filesystem::path path = scratch.path() / file_name;
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        const std::string_view bytes = as_text(data, size);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    }
    try {
        read(path);
    } catch (const InputError&) {
    } catch (const IoError&) {
    }
}

} // namespace scalemesh::fuzz
