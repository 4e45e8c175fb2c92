// io::AssignSequences: which model each logged sequence is fitted with, and io::SequenceNamesInFit:
// what it is named in the fit (sysid/io/sequence_models.h)
#include "sysid/io/sequence_models.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace mjsysid::io {
namespace {

const std::string kYaml = "/exp/pair.yaml";

ExperimentConfig Config(const std::string& models_and_sequences) {
  return ParseExperiment(models_and_sequences + R"(
parameters:
  - {name: m, target: body_mass, object: cart, initial: 1}
)",
                         kYaml);
}

Log LogOf(const std::vector<std::string>& groups) {
  Log log;
  for (const std::string& g : groups) {
    Sequence s;
    s.name = g;
    log.sequences.push_back(s);
  }
  return log;
}

const char kPair[] = R"(models:
  - {name: cart, path: cart.xml}
  - {name: cart_payload, path: cart_payload.xml}
)";

// (group, model name) pairs of an assignment
std::vector<std::pair<std::string, std::string>> Named(const ExperimentConfig& c, const Log& log,
                                                       const std::vector<SequenceOwner>& owners) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const SequenceOwner& o : owners) {
    out.emplace_back(log.sequences[o.sequence].name, c.models[o.model].name);
  }
  return out;
}

std::string ErrorOf(const ExperimentConfig& c, const Log& log) {
  try {
    AssignSequences(c, log, "/data/log.h5");
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(SequenceModelsTest, OneModelTakesEveryGroup) {
  const ExperimentConfig c = Config("model: cart.xml\n");
  const Log log = LogOf({"a", "b"});
  EXPECT_EQ(Named(c, log, AssignSequences(c, log, "/data/log.h5")),
            (std::vector<std::pair<std::string, std::string>>{{"a", "cart"}, {"b", "cart"}}));
}

TEST(SequenceModelsTest, TheLogsRecordDecidesNotTheNamePrefix) {
  const ExperimentConfig c = Config(kPair);
  Log log = LogOf({"cart_seq0", "cart_payload_seq0", "cart_payload_seq1"});
  log.attributes["sequences.cart"] = "cart_seq0";
  log.attributes["sequences.cart_payload"] = "cart_payload_seq0,cart_payload_seq1";
  EXPECT_EQ(
      Named(c, log, AssignSequences(c, log, "/data/log.h5")),
      (std::vector<std::pair<std::string, std::string>>{{"cart_seq0", "cart"},
                                                        {"cart_payload_seq0", "cart_payload"},
                                                        {"cart_payload_seq1", "cart_payload"}}));
}

TEST(SequenceModelsTest, SeveralModelsWithoutARecordIsAnErrorNamingTheFix) {
  const ExperimentConfig c = Config(kPair);
  const std::string msg = ErrorOf(c, LogOf({"cart_payload_seq0"}));
  EXPECT_NE(msg.find("/data/log.h5: sequence 'cart_payload_seq0' belongs to none of the "
                     "experiment's models (cart, cart_payload)"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("list it as `<model>/cart_payload_seq0`"), std::string::npos) << msg;
}

TEST(SequenceModelsTest, ExperimentEntriesSelectAndAssign) {
  const ExperimentConfig c =
      Config(std::string(kPair) + "sequences: [cart_payload/run1, cart/run2]\n");
  const Log log = LogOf({"run1", "run2", "run3"});
  std::vector<bool> used(c.sequences.size(), false);
  EXPECT_EQ(Named(c, log, AssignSequences(c, log, "/data/log.h5", &used)),
            (std::vector<std::pair<std::string, std::string>>{{"run1", "cart_payload"},
                                                              {"run2", "cart"}}));
  EXPECT_EQ(used, (std::vector<bool>{true, true}));
}

TEST(SequenceModelsTest, AnEntryContradictingTheRecordIsAnError) {
  const ExperimentConfig c = Config(std::string(kPair) + "sequences: [cart/s0]\n");
  Log log = LogOf({"s0"});
  log.attributes["sequences.cart_payload"] = "s0";
  const std::string msg = ErrorOf(c, log);
  EXPECT_NE(msg.find("sequence 's0' is recorded for model 'cart_payload'"), std::string::npos)
      << msg;
  EXPECT_NE(msg.find("fits it with model 'cart'"), std::string::npos) << msg;
}

TEST(SequenceModelsTest, AGroupRecordedForTwoModelsIsAnError) {
  const ExperimentConfig c = Config(kPair);
  Log log = LogOf({"s0"});
  log.attributes["sequences.cart"] = "s0";
  log.attributes["sequences.cart_payload"] = "s0";
  EXPECT_NE(ErrorOf(c, log).find("'s0' is recorded for two models"), std::string::npos);
}

TEST(SequenceModelsTest, GroupsOfAModelTheExperimentLacksAreSkipped) {
  const ExperimentConfig c = Config("models:\n  - {name: cart, path: cart.xml}\n");
  Log log = LogOf({"cart_seq0", "cart_payload_seq0"});
  log.attributes["sequences.cart"] = "cart_seq0";
  log.attributes["sequences.cart_payload"] = "cart_payload_seq0";
  EXPECT_EQ(Named(c, log, AssignSequences(c, log, "/data/log.h5")),
            (std::vector<std::pair<std::string, std::string>>{{"cart_seq0", "cart"}}));
}

TEST(SequenceModelsTest, AnEntryNoFileHasIsAConfigErrorAtItsLine) {
  const ExperimentConfig c = Config(std::string(kPair) + "sequences: [cart/nope]\n");
  try {
    CheckSequenceEntriesUsed(c, {false}, {"a", "b"});
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 4);
    EXPECT_NE(e.message().find("sequence 'cart/nope' is in none of the data files"),
              std::string::npos);
    EXPECT_EQ(e.hint(), "sequences in the data: a, b");
  }
}

// A group name selected from one log keeps it; from several logs, each is <log stem>:<group>, in
// the order given, with one line saying so.
TEST(SequenceModelsTest, AGroupNameInSeveralLogsIsNamedAfterEachFile) {
  std::vector<std::string> renamed;
  const std::vector<std::string> names = SequenceNamesInFit(
      {{"/d/runA.h5", "seq0"}, {"/d/runA.h5", "seq1"}, {"/d/runB.h5", "seq0"}}, {}, &renamed);
  EXPECT_EQ(names, (std::vector<std::string>{"runA:seq0", "seq1", "runB:seq0"}));
  ASSERT_EQ(renamed.size(), 1u);
  EXPECT_NE(renamed[0].find("sequence 'seq0' is in 2 logs (/d/runA.h5, /d/runB.h5): named "
                            "runA:seq0, runB:seq0"),
            std::string::npos)
      << renamed[0];
  EXPECT_EQ(SequenceNamesInFit({{"/d/a.h5", "x"}, {"/d/b.h5", "y"}}),
            (std::vector<std::string>{"x", "y"}));
}

// The rule looks at every group of the logs, not only the selected ones: runA's seq0 alone is
// still runA:seq0 when runB has a seq0 too (its name does not depend on the selection). An entry
// names a group by its group name in every log, or by its qualified name in its own log only.
TEST(SequenceModelsTest, NamesDependOnTheLogsNotOnTheSelection) {
  EXPECT_EQ(SequenceNamesInFit({{"/d/runA.h5", "seq0"}},
                               {{"/d/runA.h5", "seq0"}, {"/d/runB.h5", "seq0"}}),
            std::vector<std::string>{"runA:seq0"});
  SequenceRef ref;
  ref.name = "runA:seq0";
  EXPECT_EQ(QualifiedSequenceName("/d/runA.h5", "seq0"), "runA:seq0");
  EXPECT_TRUE(EntryNamesGroup(ref, "/d/runA.h5", "seq0"));
  EXPECT_FALSE(EntryNamesGroup(ref, "/d/runB.h5", "seq0"));
  ref.name = "seq0";
  EXPECT_TRUE(EntryNamesGroup(ref, "/d/runB.h5", "seq0"));
}

// Names that still collide: two logs of one stem in two folders, a group named like another log's
// renamed one: a LogError naming both files and groups.
TEST(SequenceModelsTest, NamesThatStillCollideAreAnErrorNamingBothFiles) {
  try {
    SequenceNamesInFit({{"/x/run.h5", "seq0"}, {"/y/run.h5", "seq0"}});
    ADD_FAILURE() << "no error";
  } catch (const LogError& e) {
    EXPECT_NE(std::string(e.what()).find("/x/run.h5: /seq0 and /y/run.h5: /seq0 would both be "
                                         "named 'run:seq0'"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(
      SequenceNamesInFit({{"/d/a.h5", "seq0"}, {"/d/b.h5", "seq0"}, {"/d/c.h5", "a:seq0"}}),
      LogError);
}

}  // namespace
}  // namespace mjsysid::io
