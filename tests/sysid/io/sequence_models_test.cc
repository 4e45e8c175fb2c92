// io::AssignSequences: which model each logged sequence is fitted with (sysid/io/sequence_models.h)
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

}  // namespace
}  // namespace mjsysid::io
