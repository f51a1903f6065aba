#include "server/http/web_app.h"

#include "server/http/web_files.h"

namespace gvd {

std::map<std::string, std::pair<std::string, std::string>> WebApp() {
  const std::pair<std::string, std::string> index{"text/html; charset=utf-8", web::kIndex};
  return {{"/", index},
          {"/index.html", index},
          {"/app.js", {"text/javascript; charset=utf-8", web::kApp}},
          {"/gvd-client.js", {"text/javascript; charset=utf-8", web::kGvdClient}},
          {"/style.css", {"text/css; charset=utf-8", web::kStyle}}};
}

}  // namespace gvd
