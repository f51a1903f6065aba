// The command line of every gvd program (gvd-server and gvd), read against the
// Abseil flags each defines (ABSL_FLAG): Abseil holds each flag's type, default, help and
// value, and parses values by their type; this adds what Abseil's own parser will not do,
// names spelled with hyphens (--max-scenes for ABSL_FLAG max_scenes), positional words
// among flags (negative numbers included: "gvd pick -3 4"), and a --help made from the flags'
// own help.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace gvd::flags {

struct CommandLine {
  std::vector<std::string> words;  // the positional words, in order
  // The flags given, by name as written (with hyphens, without "--"), with their text;
  // a switch (a bool flag) given as true reads "true", as false is left out.
  std::map<std::string, std::string> given;
};

// Reads `args` (argv without the program's name): "--name value", "--name=value", and
// "--name" alone for a bool flag; anything not starting with "--" is a word. Each value is
// parsed into its flag by Abseil (absl::CommandLineFlag::ParseFrom), so the flag's type says
// what it takes. INVALID_ARGUMENT, naming the flag, for an unknown flag, a missing value, a
// value the type refuses, or a word when `words` is false. "--help" and "-h" are not read
// here: look for them first (WantsHelp).
absl::StatusOr<CommandLine> Parse(const std::vector<std::string>& args, bool words);

// Whether the arguments ask for --help (or -h).
bool WantsHelp(const std::vector<std::string>& args);

// The arguments with each "--config FILE" (or --config=FILE) replaced by the flags the file
// holds: one "--flag value" per line, blank lines and "#" comments skipped. Flags after it
// on the command line override the file's.
absl::StatusOr<std::vector<std::string>> ExpandConfig(const std::vector<std::string>& args);

// The help of the flags defined in the source file whose path ends with `file`, one entry a
// flag in name order: "  --name METAVAR" then its help, wrapped at 94 columns, and its
// default. A help text that starts with "<METAVAR> " names the value that way; a flag whose
// help says "default" itself gets no default appended.
std::string Describe(const std::string& file);

}  // namespace gvd::flags
