#pragma once
// Text helpers of the file readers (internal): file contents made safe for one-line messages,
// and JSON parsed strictly.
#include <cstddef>
#include <string>

#include <nlohmann/json.hpp>

namespace penumbra {

// `text` for an error message: control and non-ASCII bytes as \xNN (so that the message stays
// on one line), cut after `max` characters with "...".
std::string printable(const std::string& text, size_t max = 40);

// JSON as nlohmann::json::parse reads it, except that an object holding the same key twice is
// an error (nlohmann would keep the last value silently): throws penumbra::Error
// "duplicate key 'PATH'", PATH as in "cameras[0].eye". Syntax errors throw nlohmann's
// exceptions, as json::parse does.
nlohmann::json parse_json(const std::string& text);

}  // namespace penumbra
