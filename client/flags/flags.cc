#include "client/flags/flags.h"

#include <algorithm>
#include <fstream>
#include <sstream>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "absl/strings/str_split.h"

namespace gvd::flags {
namespace {

absl::CommandLineFlag* Find(const std::string& name) {
  return absl::FindCommandLineFlag(absl::StrReplaceAll(name, {{"-", "_"}}));
}

}  // namespace

bool WantsHelp(const std::vector<std::string>& args) {
  return std::any_of(args.begin(), args.end(),
                     [](const std::string& a) { return a == "--help" || a == "-h"; });
}

absl::StatusOr<CommandLine> Parse(const std::vector<std::string>& args, bool words) {
  CommandLine out;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (!absl::StartsWith(arg, "--") || arg == "--") {
      if (!words) return absl::InvalidArgumentError(absl::StrCat("unexpected argument \"", arg, "\""));
      out.words.push_back(arg);
      continue;
    }
    std::string name = arg.substr(2), value;
    bool has_value = false;
    if (auto eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name.resize(eq);
      has_value = true;
    }
    absl::CommandLineFlag* flag = Find(name);
    if (flag == nullptr) return absl::InvalidArgumentError(absl::StrCat("unknown flag --", name));
    const bool is_switch = flag->IsOfType<bool>();
    if (!has_value) {
      if (is_switch) {
        value = "true";
      } else if (i + 1 < args.size()) {
        value = args[++i];
      } else {
        return absl::InvalidArgumentError(absl::StrCat("--", name, " needs a value"));
      }
    }
    std::string error;
    if (!flag->ParseFrom(value, &error)) {
      // Abseil's own words name the flag with underscores; its other errors say more.
      return absl::InvalidArgumentError(absl::StrCat(
          "--", name, " does not take \"", value, "\"",
          error.empty() || absl::StartsWith(error, "Illegal value") ? "" : ": ", 
          error.empty() || absl::StartsWith(error, "Illegal value") ? "" : error));
    }
    if (is_switch && flag->CurrentValue() != "true") {
      out.given.erase(name);
    } else {
      out.given[name] = is_switch ? "true" : value;
    }
  }
  return out;
}

absl::StatusOr<std::vector<std::string>> ExpandConfig(const std::vector<std::string>& args) {
  std::vector<std::string> out;
  for (size_t i = 0; i < args.size(); ++i) {
    std::string file;
    if (args[i] == "--config" && i + 1 < args.size()) {
      file = args[++i];
    } else if (absl::StartsWith(args[i], "--config=")) {
      file = args[i].substr(9);
    } else {
      out.push_back(args[i]);
      continue;
    }
    std::ifstream in(file);
    if (!in) return absl::InvalidArgumentError(absl::StrCat("cannot read --config file ", file));
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      std::istringstream words(line);
      std::string flag, value;
      if (!(words >> flag) || flag[0] == '#') continue;
      if (!absl::StartsWith(flag, "--")) {
        return absl::InvalidArgumentError(absl::StrCat(file, ":", n, ": expected --flag value"));
      }
      out.push_back(flag);
      if (flag.find('=') == std::string::npos && (words >> value)) out.push_back(value);
    }
  }
  return out;
}

std::string Describe(const std::string& file) {
  std::vector<const absl::CommandLineFlag*> mine;
  for (const auto& [name, flag] : absl::GetAllFlags()) {
    if (absl::EndsWith(flag->Filename(), file)) mine.push_back(flag);
  }
  std::sort(mine.begin(), mine.end(),
            [](auto* a, auto* b) { return a->Name() < b->Name(); });
  constexpr size_t kColumn = 30, kWidth = 94;
  std::string out;
  for (const absl::CommandLineFlag* flag : mine) {
    std::string help = flag->Help(), metavar;
    if (absl::StartsWith(help, "<")) {
      const size_t close = help.find("> ");
      metavar = help.substr(1, close - 1);
      help = help.substr(close + 2);
    }
    const std::string fallback = flag->DefaultValue();
    if (!absl::StrContains(help, "default") && !fallback.empty() && !flag->IsOfType<bool>()) {
      absl::StrAppend(&help, " (default ", fallback, ")");
    }
    std::string head = absl::StrCat("  --", absl::StrReplaceAll(flag->Name(), {{"_", "-"}}),
                                    metavar.empty() ? "" : " ", metavar);
    // The help, wrapped into lines that start at kColumn.
    std::string line = head.size() + 1 < kColumn ? head + std::string(kColumn - head.size(), ' ')
                                                 : head + "\n" + std::string(kColumn, ' ');
    size_t used = kColumn;  // the width of the line being written
    for (const absl::string_view word : absl::StrSplit(help, ' ', absl::SkipEmpty())) {
      if (used > kColumn && used + 1 + word.size() > kWidth) {
        absl::StrAppend(&line, "\n", std::string(kColumn, ' '));
        used = kColumn;
      } else if (used > kColumn) {
        line += ' ';
        ++used;
      }
      absl::StrAppend(&line, word);
      used += word.size();
    }
    absl::StrAppend(&out, line, "\n");
  }
  return out;
}

}  // namespace gvd::flags
