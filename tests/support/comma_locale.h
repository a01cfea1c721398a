#pragma once
// A comma-decimal LC_NUMERIC for one test, as a host application (a Qt GUI, a
// German desktop) may have set it before calling the library: glibc's de_DE,
// compiled by localedef (the locales package ships its source) into a scratch
// directory named by LOCPATH. The process's numeric locale and LOCPATH come
// back however the test ends.

#include "temp_dir.h"

#include <clocale>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace scalemesh {

class CommaNumericLocale {
public:
    CommaNumericLocale()
    {
        const std::filesystem::path locale = dir_.path / "de_DE.UTF-8";
        const std::string compile = "localedef -c -i de_DE -f UTF-8 '" + locale.string() + "' >/dev/null 2>&1";
        (void)std::system(compile.c_str()); // -c: written despite warnings, which set the exit code
        if (!std::filesystem::exists(locale / "LC_NUMERIC")) {
            failure_ = "localedef could not compile de_DE (setup.sh installs the locales package)";
            return;
        }
        ::setenv("LOCPATH", dir_.path.c_str(), 1);
        if (!std::setlocale(LC_NUMERIC, "de_DE.UTF-8"))
            failure_ = "setlocale(LC_NUMERIC, \"de_DE.UTF-8\") refused the compiled locale";
        else if (std::string(std::localeconv()->decimal_point) != ",")
            failure_ = std::string("the compiled locale's decimal point is '") + std::localeconv()->decimal_point + "'";
    }
    ~CommaNumericLocale()
    {
        std::setlocale(LC_NUMERIC, numeric_.c_str());
        if (had_path_) ::setenv("LOCPATH", path_.c_str(), 1);
        else ::unsetenv("LOCPATH");
    }
    CommaNumericLocale(const CommaNumericLocale&) = delete;
    CommaNumericLocale& operator=(const CommaNumericLocale&) = delete;

    // Empty when the comma locale is in effect, else why it is not.
    const std::string& failure() const { return failure_; }

private:
    std::string numeric_ = std::setlocale(LC_NUMERIC, nullptr);
    bool had_path_ = std::getenv("LOCPATH") != nullptr;
    std::string path_ = had_path_ ? std::getenv("LOCPATH") : "";
    TempDir dir_;
    std::string failure_;
};

} // namespace scalemesh
