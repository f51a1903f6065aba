// A server's Prometheus endpoint as the tests read it: the port it logged, a scrape, and a
// wait for a line to appear.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <regex>
#include <string>
#include <thread>

namespace gvd::testing {

// The metrics port a server logged ("event=metrics ... port=N"), or 0.
inline int MetricsPort(const std::string& log) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex("event=metrics address=\\S+ port=(\\d+)"))) return 0;
  return std::stoi(m[1]);
}

// GET http://127.0.0.1:port/metrics; the body, or "" on failure.
inline std::string Scrape(int port) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    close(fd);
    return "";
  }
  std::string request = "GET /metrics HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  if (write(fd, request.data(), request.size()) != ssize_t(request.size())) {
    close(fd);
    return "";
  }
  std::string response;
  char buf[4096];
  ssize_t n;
  while ((n = read(fd, buf, sizeof buf)) > 0) response.append(buf, n);
  close(fd);
  auto body = response.find("\r\n\r\n");
  return body == std::string::npos ? "" : response.substr(body + 4);
}

// Polls the metrics until `line` appears (up to `seconds`); the last scrape.
inline std::string WaitForMetric(int port, const std::string& line, int seconds) {
  std::string text;
  for (int tries = 0; tries < seconds * 20; ++tries) {
    text = Scrape(port);
    if (text.find(line) != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return text;
}

}  // namespace gvd::testing
