#pragma once
// The exception family of scalemesh. The library never prints and never exits;
// the command line maps these to one line on stderr and an exit code.

#include <stdexcept>
#include <string>

namespace scalemesh {

class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
    // Process exit code the command line uses for this kind of error.
    virtual int exit_code() const { return 1; }
};

// The user's input is wrong: a bad file, parameter or case. The message says
// what is wrong and what to do about it.
class InputError : public Error {
public:
    InputError(const std::string& what, const std::string& hint)
        : Error(hint.empty() ? what : what + ". Hint: " + hint)
    {
    }
    int exit_code() const override { return 2; }
};

// A file could not be read or written.
class IoError : public Error {
public:
    IoError(const std::string& path, const std::string& what) : Error(path + ": " + what) {}
    int exit_code() const override { return 3; }
};

// A stage failed to establish a fact it promises; names the stage and the
// offending element ids.
class StageError : public Error {
public:
    StageError(const std::string& stage, const std::string& what) : Error(stage + ": " + what) {}
    int exit_code() const override { return 4; }
};

} // namespace scalemesh
