// Keys and paths taken from a store's metadata (a precomputed scale's "key", an NGFF dataset "path", a
// label group's name, a max-pyramid group) are untrusted: they must name objects inside the store and
// nowhere else, whether the store is a local directory (the kernel resolves ".." and symlinks) or an
// HTTP URL (the server percent-decodes the path and removes dot segments). Every ByteStore passes each
// key through store_key() before it touches a file or sends a request, so no reader can forget it.
#pragma once

#include <string>
#include <string_view>

namespace sl {

// `key` in normal form ("." segments dropped, no empty segment, no leading or trailing '/'), or
// std::runtime_error("key 'K' ...why") when it could leave the store or be read differently by a
// server: a ".." segment (in the key as written or after any number of percent-decodings, so
// "%2e%2e/", "%252e%252e/" and "%2E%2E%2F" count), an absolute path, a backslash, a NUL or other control
// byte, a '?' or '#', an empty segment ("a//b"), or a '%' that is not a valid escape. A key of "" or
// "." names the store's root (returns "").
std::string store_key(std::string_view key);

// The text of `key` with control bytes escaped, bounded in length, for messages.
std::string printable_key(std::string_view key);

// The file a local store reads for `key`: root + "/" + store_key(key).
std::string local_store_path(const std::string& root, std::string_view key);
// The URL an HTTP store fetches for `key`: base (without trailing '/') + "/" + store_key(key).
std::string store_url(const std::string& base, std::string_view key);

// True when the file open as `fd` lies inside the directory `canonical_root` (a realpath), read from
// /proc/self/fd so that the check applies to the file actually opened, after every symlink.
bool fd_inside(int fd, const std::string& canonical_root, std::string* where = nullptr);

}  // namespace sl
