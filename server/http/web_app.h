// The web app gvd-server serves at / of its HTTP port (web/: plain HTML, CSS and JavaScript
// modules, no build step), embedded in the binary at build time.
#pragma once

#include <map>
#include <string>
#include <utility>

namespace gvd {

// Path ("/", "/app.js") to (content type, body).
std::map<std::string, std::pair<std::string, std::string>> WebApp();

}  // namespace gvd
