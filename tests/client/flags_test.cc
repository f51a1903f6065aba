// The command line of gvd's programs (client/flags/flags.h), read against flags of this test's own.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/reflection.h"
#include "client/flags/flags.h"

ABSL_FLAG(uint64_t, flags_test_count, 7, "<N> a count");
ABSL_FLAG(std::string, flags_test_name, "", "<NAME> a name whose help is long enough to wrap "
          "onto a second line of the help, at ninety-four columns, by words");
ABSL_FLAG(bool, flags_test_switch, false, "a switch");

namespace gvd::flags {
namespace {

class FlagsTest : public ::testing::Test {
 protected:
  absl::FlagSaver saver_;  // each test starts from the defaults
};

TEST_F(FlagsTest, HyphensValuesSwitchesAndWords) {
  auto cl = Parse({"pick", "--flags-test-count", "12", "-3.5", "--flags-test-switch",
                   "--flags-test-name=a b", "4"},
                  /*words=*/true);
  ASSERT_TRUE(cl.ok()) << cl.status();
  EXPECT_EQ(absl::GetFlag(FLAGS_flags_test_count), 12u);
  EXPECT_EQ(absl::GetFlag(FLAGS_flags_test_name), "a b");
  EXPECT_TRUE(absl::GetFlag(FLAGS_flags_test_switch));
  EXPECT_EQ(cl->words, (std::vector<std::string>{"pick", "-3.5", "4"}));
  EXPECT_EQ(cl->given.at("flags-test-count"), "12");
  EXPECT_EQ(cl->given.at("flags-test-switch"), "true");
  // A switch set false is not "given"; a value may start with a minus sign.
  cl = Parse({"--flags-test-switch=false", "--flags-test-name", "-x"}, true);
  ASSERT_TRUE(cl.ok()) << cl.status();
  EXPECT_FALSE(cl->given.count("flags-test-switch"));
  EXPECT_EQ(absl::GetFlag(FLAGS_flags_test_name), "-x");
}

TEST_F(FlagsTest, RefusalsNameTheFlag) {
  auto unknown = Parse({"--flags-test-nothing", "1"}, true);
  EXPECT_EQ(unknown.status().message(), "unknown flag --flags-test-nothing");
  auto missing = Parse({"--flags-test-count"}, true);
  EXPECT_EQ(missing.status().message(), "--flags-test-count needs a value");
  auto typed = Parse({"--flags-test-count", "-2"}, true);
  EXPECT_EQ(typed.status().message(), "--flags-test-count does not take \"-2\"");
  auto word = Parse({"stray"}, /*words=*/false);
  EXPECT_EQ(word.status().message(), "unexpected argument \"stray\"");
  EXPECT_TRUE(WantsHelp({"x", "-h"}));
  EXPECT_FALSE(WantsHelp({"--flags-test-name", "help"}));
}

TEST_F(FlagsTest, ConfigFilesExpandInPlace) {
  const std::string path = ::testing::TempDir() + "/flags_test.conf";
  std::ofstream(path) << "# a comment\n\n--flags-test-count 3\n--flags-test-name=from-file\n";
  auto expanded = ExpandConfig({"--config", path, "--flags-test-count", "5"});
  ASSERT_TRUE(expanded.ok()) << expanded.status();
  EXPECT_EQ(*expanded, (std::vector<std::string>{"--flags-test-count", "3",
                                                 "--flags-test-name=from-file",
                                                 "--flags-test-count", "5"}));
  EXPECT_FALSE(ExpandConfig({"--config=/nonexistent/gvd.conf"}).ok());
  std::ofstream(path) << "flags-test-count 3\n";
  EXPECT_EQ(ExpandConfig({"--config", path}).status().message(),
            path + ":1: expected --flag value");
  std::remove(path.c_str());
}

TEST_F(FlagsTest, HelpFromTheFlagsOwnHelp) {
  const std::string help = Describe("tests/client/flags_test.cc");
  EXPECT_EQ(help,
            "  --flags-test-count N        a count (default 7)\n"
            "  --flags-test-name NAME      a name whose help is long enough to wrap onto a second "
            "line of\n"
            "                              the help, at ninety-four columns, by words\n"
            "  --flags-test-switch         a switch\n");
}

}  // namespace
}  // namespace gvd::flags
