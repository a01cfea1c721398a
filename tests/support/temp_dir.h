#pragma once
// A scratch directory for one test, removed with everything in it at the end.

#include <algorithm>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace scalemesh {

struct TempDir {
    std::filesystem::path path;
    TempDir()
    {
        std::random_device rd;
        path = std::filesystem::temp_directory_path() / ("scalemesh-test-" + std::to_string(rd()) + std::to_string(rd()));
        std::filesystem::create_directories(path);
    }
    ~TempDir()
    {
        std::error_code ignored;
        std::filesystem::remove_all(path, ignored);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    // Files below the directory, sorted, relative to it.
    std::vector<std::string> files() const
    {
        std::vector<std::string> out;
        for (const auto& e : std::filesystem::recursive_directory_iterator(path))
            out.push_back(std::filesystem::relative(e.path(), path).string());
        std::sort(out.begin(), out.end());
        return out;
    }
};

} // namespace scalemesh
