// Files under the data directory. Results are written atomically: a temporary file next to the target,
// flushed to disk, then renamed over it, so a reader (or a restarted server) sees the old file or the
// whole new one, never a part.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace moreau::server {

enum class Durability {
  kRename,  // atomic against a crash of the process (rename), not against a power loss
  kFsync,   // also fsync the file before the rename
};

// Writes `bytes` to `path` through `path`.tmp and a rename. Throws std::runtime_error naming the file;
// a failed write leaves no temporary file behind.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes, Durability durability);

// Writes `bytes` to `path` (created or truncated), without fsync. Throws std::runtime_error, and removes
// the file, if the write fails.
void write_file(const std::filesystem::path& path, std::string_view bytes);

// Creates and removes a file in `dir`; throws std::runtime_error naming the directory if that fails
// (read-only file system, no permission). Does not check free space.
void check_writable_directory(const std::filesystem::path& dir);

// fsync of a file or directory (a directory: so that renames inside it survive a power loss).
void fsync_path(const std::filesystem::path& path);

// The whole file, or nullopt if it cannot be opened.
std::optional<std::string> read_file(const std::filesystem::path& path);

// A test seam: when set, each file write first asks it; a non-zero errno (ENOSPC, say) makes that write
// fail as the disk would. Set only by tests, before the server starts, and cleared after it stops.
std::function<int(const std::filesystem::path&)>& write_fault_for_testing();

// Job ids: 32 lowercase hex digits (128 random bits).
bool is_job_id(std::string_view s);
std::string new_job_id();

}  // namespace moreau::server
