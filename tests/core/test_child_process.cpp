#include "core/child_process.h"

#include <gtest/gtest.h>

#include <csignal>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace {

using scalemesh::ChildProcessError;
using scalemesh::run_in_child_process;

// Set by the handler a parent installs; the child must not run it.
volatile std::sig_atomic_t handled = 0;
void on_signal(int) { handled = 1; }

TEST(ChildProcess, ReturnsTheChildsBytesWhole)
{
    // Larger than a pipe's buffer, with every byte value in it.
    std::string expected(3 << 20, '\0');
    for (size_t i = 0; i < expected.size(); ++i) expected[i] = static_cast<char>(i * 2654435761u >> 13);
    EXPECT_EQ(run_in_child_process([&] { return expected; }), expected);
    EXPECT_EQ(run_in_child_process([] { return std::string(); }), "");
}

TEST(ChildProcess, WhatTheChildChangesStaysThere)
{
    int value = 1;
    const std::string answer = run_in_child_process([&] {
        value = 2;
        return std::to_string(getpid());
    });
    EXPECT_EQ(value, 1);
    EXPECT_NE(answer, std::to_string(getpid()));
}

TEST(ChildProcess, AnExceptionComesBackWithItsMessage)
{
    try {
        run_in_child_process([]() -> std::string { throw std::runtime_error("the boundary lost a triangle"); });
        FAIL() << "no error";
    } catch (const ChildProcessError& e) {
        EXPECT_STREQ(e.what(), "the boundary lost a triangle");
        EXPECT_TRUE(e.threw());
        EXPECT_FALSE(e.interrupted());
    }
}

TEST(ChildProcess, ACrashIsAnErrorOfTheParent)
{
    try {
        run_in_child_process([]() -> std::string { std::abort(); });
        FAIL() << "no error";
    } catch (const ChildProcessError& e) {
        EXPECT_FALSE(e.threw());
        EXPECT_EQ(e.signal(), SIGABRT);
        EXPECT_FALSE(e.interrupted()); // a crash of its own
        EXPECT_NE(std::string(e.what()).find("was killed by signal " + std::to_string(SIGABRT)), std::string::npos)
            << e.what();
    }
    // Exiting without an answer, as after a sanitizer's report.
    try {
        run_in_child_process([]() -> std::string { _exit(3); });
        FAIL() << "no error";
    } catch (const ChildProcessError& e) {
        EXPECT_FALSE(e.threw());
        EXPECT_EQ(e.signal(), 0);
        EXPECT_EQ(e.exit_status(), 3);
        EXPECT_NE(std::string(e.what()).find("exited with status 3"), std::string::npos) << e.what();
    }
    // exit() inside the work ends the child before the parent's atexit
    // handlers run there.
    try {
        run_in_child_process([]() -> std::string { std::exit(0); });
        FAIL() << "no error";
    } catch (const ChildProcessError& e) {
        EXPECT_EQ(e.exit_status(), 2) << e.what();
    }
}

TEST(ChildProcess, TheParentsInterruptHandlerIsNotRunInTheChild)
{
    const auto previous = std::signal(SIGTERM, on_signal);
    handled = 0;
    try {
        run_in_child_process([]() -> std::string {
            std::raise(SIGTERM);
            return handled ? "handled" : "not killed";
        });
        FAIL() << "the child outlived SIGTERM";
    } catch (const ChildProcessError& e) {
        EXPECT_EQ(e.signal(), SIGTERM) << e.what();
        EXPECT_TRUE(e.interrupted()); // not a crash: the caller stops
    }
    EXPECT_EQ(handled, 0);
    std::signal(SIGTERM, previous);
}

} // namespace
