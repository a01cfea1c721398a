#include "polymesh_files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <regex>
#include <sstream>

namespace scalemesh {

namespace {

std::string slurp(const std::filesystem::path& file)
{
    std::ifstream in(file);
    EXPECT_TRUE(in) << file;
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

} // namespace

std::vector<int64_t> read_numbers(const std::filesystem::path& file)
{
    std::string body = slurp(file);
    const size_t header = body.find("}\n");
    EXPECT_NE(header, std::string::npos) << file;
    if (header == std::string::npos) return {};
    body = body.substr(header + 2);
    body = body.substr(0, body.find("//"));
    std::replace(body.begin(), body.end(), '(', ' ');
    std::replace(body.begin(), body.end(), ')', ' ');
    std::istringstream words(body);
    std::vector<int64_t> out;
    for (int64_t v; words >> v;) out.push_back(v);
    return out;
}

std::vector<int64_t> read_label_list(const std::filesystem::path& file)
{
    std::vector<int64_t> v = read_numbers(file);
    EXPECT_FALSE(v.empty()) << file;
    if (v.empty()) return v;
    EXPECT_EQ(v[0], static_cast<int64_t>(v.size()) - 1) << file;
    v.erase(v.begin());
    return v;
}

std::vector<std::vector<int32_t>> read_face_list(const std::filesystem::path& file)
{
    const std::vector<int64_t> v = read_numbers(file);
    std::vector<std::vector<int32_t>> faces;
    for (size_t at = 1; at < v.size(); at += static_cast<size_t>(v[at]) + 1) {
        if (v[at] < 1) {
            ADD_FAILURE() << file << ": a face of " << v[at] << " points";
            break;
        }
        const size_t end = std::min(v.size(), at + static_cast<size_t>(v[at]) + 1);
        faces.emplace_back(v.begin() + static_cast<std::ptrdiff_t>(at) + 1, v.begin() + static_cast<std::ptrdiff_t>(end));
    }
    EXPECT_EQ(static_cast<int64_t>(faces.size()), v.empty() ? -1 : v[0]) << file;
    return faces;
}

std::vector<BoundaryPatch> read_boundary(const std::filesystem::path& file)
{
    const std::string s = slurp(file);
    std::vector<BoundaryPatch> patches;
    const std::regex entry(R"(\n    (\w+)\n    \{([^}]*)\})");
    for (auto it = std::sregex_iterator(s.begin(), s.end(), entry); it != std::sregex_iterator(); ++it) {
        BoundaryPatch p{(*it)[1].str()};
        const std::string body = (*it)[2].str();
        std::smatch m;
        if (std::regex_search(body, m, std::regex(R"(nFaces\s+(\d+))"))) p.faces = std::stoll(m[1]);
        if (std::regex_search(body, m, std::regex(R"(startFace\s+(\d+))"))) p.start = std::stoll(m[1]);
        if (std::regex_search(body, m, std::regex(R"(neighbProcNo\s+(\d+))"))) p.neighbour = std::stoll(m[1]);
        patches.push_back(p);
    }
    return patches;
}

} // namespace scalemesh
