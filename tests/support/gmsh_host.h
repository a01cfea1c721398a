#pragma once
// What scalemesh leaves of a host's Gmsh session it ran inside: the host's
// model current again and listed once.

#include <gmsh.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace scalemesh {

// Use as EXPECT_TRUE(host_model_current_and_listed_once("host")): a failure
// names the current model and how often the host's is listed.
inline ::testing::AssertionResult host_model_current_and_listed_once(const std::string& host)
{
    std::string current;
    gmsh::model::getCurrent(current);
    std::vector<std::string> models;
    gmsh::model::list(models);
    const auto listed = std::count(models.begin(), models.end(), host);
    if (current == host && listed == 1) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "the current model is \"" << current << "\" and \"" << host
                                         << "\" is listed " << listed << " times";
}

} // namespace scalemesh
