// Errors as values across library boundaries (meshoptimizer/gltfpack style: one clear
// message per failure, and a kind that maps to the CLI's exit code).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace shadowcull {

enum class ErrorKind {
    BadInput,         // malformed file, bad number, non-finite value, bad name ... (exit 3)
    MissingResource,  // a referenced file does not exist or cannot be opened (exit 3)
    Io,               // writing failed (exit 4)
    Internal,         // a library (Embree, CGAL, GL) failed (exit 5)
    Busy,             // another process holds the lock on what this one would write (exit 6)
    StalePlan,        // a shard's plan (shadowcull plan) no longer matches the space (exit 9)
    Interrupted,      // SIGINT or SIGTERM: stopped, temporary files removed (exit 128 + signal)
};

// A failure: which file, which line (0 when the file has no lines, e.g. binary data),
// and what went wrong. `what()` formats it as "file:line: message".
struct Error {
    ErrorKind kind = ErrorKind::BadInput;
    std::string file;
    int line = 0;
    std::string message;

    std::string what() const {
        std::string s = file;
        if (!s.empty() && line > 0) s += ":" + std::to_string(line);
        if (!s.empty()) s += ": ";
        return s + message;
    }
};

inline Error makeError(ErrorKind kind, std::string file, int line, std::string message) {
    return Error{kind, std::move(file), line, std::move(message)};
}

// Status: success or one Error.
class Status {
public:
    Status() = default;
    Status(Error e) : error_(std::move(e)) {}  // NOLINT: implicit on purpose (return makeError(...))
    static Status ok() { return Status(); }
    bool isOk() const { return !error_.has_value(); }
    explicit operator bool() const { return isOk(); }
    const Error& error() const { return *error_; }

private:
    std::optional<Error> error_;
};

// Expected<T>: a value or one Error.
template <class T>
class Expected {
public:
    Expected(T value) : v_(std::move(value)) {}  // NOLINT
    Expected(Error e) : v_(std::move(e)) {}      // NOLINT
    bool isOk() const { return v_.index() == 0; }
    explicit operator bool() const { return isOk(); }
    T& value() & { return std::get<0>(v_); }
    const T& value() const& { return std::get<0>(v_); }
    T&& value() && { return std::get<0>(std::move(v_)); }
    T* operator->() { return &std::get<0>(v_); }
    const T* operator->() const { return &std::get<0>(v_); }
    T& operator*() { return value(); }
    const T& operator*() const { return value(); }
    const Error& error() const { return std::get<1>(v_); }
    Status status() const { return isOk() ? Status() : Status(error()); }

private:
    std::variant<T, Error> v_;
};

}  // namespace shadowcull
