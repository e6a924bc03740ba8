#pragma once
// Helpers of the file readers and writers (internal): whole files read, file contents made safe
// for one-line messages, quoted paths, the shape check of images to write, and JSON parsed
// strictly.
#include <cstddef>
#include <string>

#include <nlohmann/json.hpp>

#include "penumbra/image.hpp"

namespace penumbra {

// `text` for an error message: control and non-ASCII bytes as \xNN (so that the message stays
// on one line), cut after `max` characters with "...".
std::string printable(const std::string& text, size_t max = 40);

// "'path'", as messages quote file names.
std::string quoted_path(const std::string& path);

// A library's multi-line message on one line: runs of white space as one space.
std::string one_line(const std::string& text);

// The bytes of the file at `path`; throws penumbra::Error "cannot open <what> '<path>': ..."
// (or read), naming a folder as such.
std::string read_whole_file(const std::string& path, const std::string& what);

// Throws penumbra::Error "cannot write <what> '<path>': ..." unless `image` is non-empty and
// holds width × height × channels values.
void check_image(const Image& image, const std::string& what, const std::string& path);

// JSON as nlohmann::json::parse reads it, except that an object holding the same key twice is
// an error (nlohmann would keep the last value silently): throws penumbra::Error
// "duplicate key 'PATH'", PATH as in "cameras[0].eye"; so is nesting deeper than 64 levels of
// objects and arrays (refused where it starts). Syntax errors throw nlohmann's
// exceptions, as json::parse does.
nlohmann::json parse_json(const std::string& text);

}  // namespace penumbra
