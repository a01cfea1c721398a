#pragma once
// Running the scalemesh binary from tests, in scratch directories.

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <sys/wait.h>
#include <vector>

#include "support/temp_dir.h"

namespace scalemesh {

struct CommandResult {
    int exit_code = -1;
    std::string err; // stderr
    std::string out; // stdout
};

inline std::string quote(const std::string& s)
{
    std::string out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

// Runs the binary named by $SCALEMESH_BINARY (set by ctest) with `args`.
inline CommandResult run_scalemesh(const std::vector<std::string>& args)
{
    const char* binary = std::getenv("SCALEMESH_BINARY");
    if (!binary) throw std::runtime_error("SCALEMESH_BINARY is not set; run the tests through ctest");
    const std::string id = std::to_string(std::random_device{}());
    const std::filesystem::path err_file = std::filesystem::temp_directory_path() / ("scalemesh-stderr-" + id);
    const std::filesystem::path out_file = std::filesystem::temp_directory_path() / ("scalemesh-stdout-" + id);
    std::string cmd = quote(binary);
    for (const std::string& a : args) {
        cmd += ' ';
        cmd += quote(a);
    }
    cmd += " </dev/null >" + quote(out_file.string()) + " 2>" + quote(err_file.string());
    const int status = std::system(cmd.c_str());
    CommandResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    for (const auto& [file, text] : {std::pair{&err_file, &r.err}, std::pair{&out_file, &r.out}}) {
        if (FILE* f = std::fopen(file->c_str(), "r")) {
            std::array<char, 4096> buf;
            size_t n;
            while ((n = std::fread(buf.data(), 1, buf.size(), f)) > 0) text->append(buf.data(), n);
            std::fclose(f);
        }
        std::filesystem::remove(*file);
    }
    return r;
}

} // namespace scalemesh
