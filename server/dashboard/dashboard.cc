#include "server/dashboard/dashboard.h"

#include <httplib.h>

#include <charconv>

#include "absl/strings/str_cat.h"

namespace totalgrad::dashboard {
namespace {

using nlohmann::json;

// The page loads only its own files: no inline script, no other origin.
void SetCommonHeaders(httplib::Response& response) {
  response.set_header("Cache-Control", "no-store");
  response.set_header("X-Content-Type-Options", "nosniff");
  response.set_header("X-Frame-Options", "DENY");
  response.set_header("Referrer-Policy", "no-referrer");
  response.set_header("Content-Security-Policy",
                      "default-src 'self'; script-src 'self'; style-src 'self'; "
                      "img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'");
}

int HttpStatus(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kInvalidArgument: return 400;
    case absl::StatusCode::kUnauthenticated: return 401;
    case absl::StatusCode::kPermissionDenied: return 403;
    case absl::StatusCode::kNotFound: return 404;
    case absl::StatusCode::kUnavailable: return 503;
    default: return 500;
  }
}

void SendError(const absl::Status& status, httplib::Response& response) {
  response.status = HttpStatus(status);
  response.set_content(json{{"error", std::string(status.message())}}.dump(),
                       "application/json; charset=utf-8");
}

absl::StatusOr<std::string> RequiredParameter(const httplib::Request& request, const char* name) {
  if (!request.has_param(name) || request.get_param_value(name).empty()) {
    return absl::InvalidArgumentError(absl::StrCat("the query parameter '", name, "' is required"));
  }
  return request.get_param_value(name);
}

// An integer parameter, or `fallback` when absent. InvalidArgument names it.
absl::StatusOr<int64_t> IntegerParameter(const httplib::Request& request, const char* name,
                                         int64_t fallback) {
  if (!request.has_param(name)) return fallback;
  const std::string text = request.get_param_value(name);
  int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the query parameter '", name, "' must be an integer, got '", text, "'"));
  }
  return value;
}

const char* ContentType(std::string_view name) {
  if (name.ends_with(".html")) return "text/html; charset=utf-8";
  if (name.ends_with(".js")) return "text/javascript; charset=utf-8";
  if (name.ends_with(".css")) return "text/css; charset=utf-8";
  return "application/octet-stream";
}

}  // namespace

void Dashboard::Register(httplib::Server* server) {
  auto serve_file = [](const char* file) {
    return [file](const httplib::Request&, httplib::Response& response) {
      SetCommonHeaders(response);
      const std::optional<std::string_view> bytes = EmbeddedFile(file);
      if (!bytes) {
        response.status = 404;
        return;
      }
      response.set_content(bytes->data(), bytes->size(), ContentType(file));
    };
  };
  server->Get("/", serve_file("index.html"));
  server->Get("/dashboard.js", serve_file("dashboard.js"));
  server->Get("/inside_trials.js", serve_file("inside_trials.js"));
  server->Get("/figures.js", serve_file("figures.js"));
  server->Get("/dashboard.css", serve_file("dashboard.css"));

  // Every API route: authorise, build the document, answer.
  using Builder = std::function<absl::StatusOr<json>(const httplib::Request&)>;
  auto api = [this, server](const char* path, Builder build) {
    server->Get(path, [this, build = std::move(build)](const httplib::Request& request,
                                                      httplib::Response& response) {
      SetCommonHeaders(response);
      std::string authorization;
      const bool has = request.has_header("Authorization");
      if (has) authorization = request.get_header_value("Authorization");
      const absl::Status allowed = authorize_(has ? &authorization : nullptr);
      if (!allowed.ok()) {
        SendError(allowed, response);
        return;
      }
      const absl::StatusOr<json> document = build(request);
      if (!document.ok()) {
        SendError(document.status(), response);
        return;
      }
      // Replace, not throw, on text that is not UTF-8 (a worker's error text).
      response.set_content(document->dump(-1, ' ', false, json::error_handler_t::replace),
                           "application/json; charset=utf-8");
    });
  };
  api("/api/overview", [this](const httplib::Request&) { return data_.Overview(now_ms_()); });
  api("/api/sweep", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> name = RequiredParameter(request, "name");
    if (!name.ok()) return name.status();
    return data_.Sweep(*name, now_ms_());
  });
  api("/api/curves", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> name = RequiredParameter(request, "name");
    if (!name.ok()) return name.status();
    absl::StatusOr<int64_t> running = IntegerParameter(request, "running", 1);
    if (!running.ok()) return running.status();
    return data_.Curves(*name, *running != 0);
  });
  api("/api/compare", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> name = RequiredParameter(request, "name");
    if (!name.ok()) return name.status();
    return data_.Compare(*name, request.get_param_value("baseline"));
  });
  api("/api/table1", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    std::vector<std::string> names;
    for (size_t i = 0; i < request.get_param_value_count("name"); ++i) {
      names.push_back(request.get_param_value("name", i));
    }
    if (names.empty()) return RequiredParameter(request, "name").status();
    return data_.Table1(names);
  });
  api("/api/jobs", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> name = RequiredParameter(request, "name");
    if (!name.ok()) return name.status();
    absl::StatusOr<int64_t> after = IntegerParameter(request, "after", 0);
    if (!after.ok()) return after.status();
    absl::StatusOr<int64_t> limit = IntegerParameter(request, "limit", 1000);
    if (!limit.ok()) return limit.status();
    if (*limit < 1 || *limit > 10000) {
      return absl::InvalidArgumentError("the query parameter 'limit' must be in 1..10000");
    }
    return data_.Jobs(*name, *after, static_cast<int>(*limit));
  });
  api("/api/job", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> id_text = RequiredParameter(request, "id");
    if (!id_text.ok()) return id_text.status();
    absl::StatusOr<int64_t> id = IntegerParameter(request, "id", 0);
    if (!id.ok()) return id.status();
    return data_.Job(*id);
  });
  api("/api/trajectory", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> id_text = RequiredParameter(request, "id");
    if (!id_text.ok()) return id_text.status();
    absl::StatusOr<int64_t> id = IntegerParameter(request, "id", 0);
    if (!id.ok()) return id.status();
    absl::StatusOr<int64_t> episode = IntegerParameter(request, "episode", 0);
    if (!episode.ok()) return episode.status();
    absl::StatusOr<int64_t> rollout = IntegerParameter(request, "rollout", -1);
    if (!rollout.ok()) return rollout.status();
    if (*episode < 0 || *episode > 100000 || *rollout < -1 || *rollout > 1000000) {
      return absl::InvalidArgumentError("'episode' must be >= 0 and 'rollout' >= 0 (or absent)");
    }
    return data_.Trajectory(*id, static_cast<int>(*episode), static_cast<int>(*rollout));
  });
  api("/api/diagnostics", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> name = RequiredParameter(request, "name");
    if (!name.ok()) return name.status();
    absl::StatusOr<std::string> statistic = RequiredParameter(request, "statistic");
    if (!statistic.ok()) return statistic.status();
    return data_.Diagnostics(*name, *statistic);
  });
  api("/api/final_trajectories", [this](const httplib::Request& request) -> absl::StatusOr<json> {
    absl::StatusOr<std::string> name = RequiredParameter(request, "name");
    if (!name.ok()) return name.status();
    return data_.FinalTrajectories(*name);
  });
}

}  // namespace totalgrad::dashboard
