#pragma once
// Scoped access to the Gmsh SDK, whose state is global to the process.
//
// Gmsh 4.8 has no gmsh::isInitialized, and no call can ask safely: before the
// first gmsh::initialize of the process, any other call reports an error
// through options that hold whatever the memory held, which now and then
// ends the process (exit(1), without a word). scalemesh therefore reaches
// Gmsh only through GmshSession, which counts the open sessions: the first
// one initializes Gmsh, the last one finalizes it, and nested sessions share
// it. A host's own session (the library's mesh_gmsh_model) is adopted for
// the length of a call, so that nested sessions neither initialize nor
// finalize it. Code that calls gmsh::initialize directly must not hold Gmsh
// while a GmshSession is open.

#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace scalemesh {

class GmshSession {
public:
    // Locks the process-wide Gmsh mutex for the session's lifetime (Gmsh is not
    // thread safe; nested sessions on one thread are allowed), initializes Gmsh
    // without reading the user's configuration files when no session is open,
    // and silences its terminal output: the library never prints.
    GmshSession();
    // The host's session, open already: counted and locked as a session of
    // ours, never finalized, its options untouched.
    struct Host {};
    explicit GmshSession(Host);
    // Restores every option changed through set_option, then finalizes Gmsh
    // when this session initialized it. Never throws.
    ~GmshSession();
    GmshSession(const GmshSession&) = delete;
    GmshSession& operator=(const GmshSession&) = delete;

    // gmsh::option::setNumber, with the previous value restored at the end of
    // the session so that an enclosing session sees its own settings again.
    void set_option(const std::string& name, double value);

private:
    std::unique_lock<std::recursive_mutex> lock_;
    bool started_ = false;
    std::vector<std::pair<std::string, double>> saved_options_;
};

// A Gmsh model, and the views made for it, that exist for one operation only.
// Made current on construction; on destruction the views and the model are
// removed and the previously current model is current again, so that an
// enclosing session finds Gmsh as it left it. Use inside a GmshSession.
class ScratchModel {
public:
    explicit ScratchModel(const std::string& prefix); // the name is prefix + a unique number
    ~ScratchModel();                                   // never throws
    ScratchModel(const ScratchModel&) = delete;
    ScratchModel& operator=(const ScratchModel&) = delete;

    const std::string& name() const { return name_; }
    // gmsh::view::add; the view is removed with the model.
    int add_view(const std::string& view_name);
    // Views created by other calls (gmsh::merge) that are removed with the model.
    void adopt_views(const std::vector<int>& tags);

private:
    std::string name_;
    std::string previous_;
    std::vector<int> views_;
};

// Inserts a $Comments section right after the $MeshFormat section of the
// .msh file at `path` (ASCII or binary: the header is text either way).
// Gmsh, like gmshToFoam, skips sections it does not know, so the lines are
// for people and provenance tools only. Lines must not begin with '$'.
// Throws IoError.
void insert_msh_comments(const std::filesystem::path& path, const std::vector<std::string>& lines);

} // namespace scalemesh
