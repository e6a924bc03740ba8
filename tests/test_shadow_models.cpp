// The shadow-model axis: every ShadowModel below Count has its row in shadow_models(), whose
// word the scene files, the command line and Python take, and its row in the renderer's table
// (shadow_model_passes), so that a model added to the enum without them fails here rather than
// taking another model's branch. (The renderer's table also stops the build: a static_assert.)
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/error.hpp"
#include "penumbra/scene.hpp"
#include "shadow_models.hpp"

using penumbra::ShadowModel;

namespace {

// `penumbra <args>`, its output in files named after `tag` (cli_run.hpp).
penumbra_tests::RunResult run_cli(const std::string& args, const std::string& tag) {
  const std::string at = ::testing::TempDir() + "penumbra_shadow_models_" + tag;
  return penumbra_tests::run_cli_to(args, at + ".stdout", at + ".stderr");
}

std::vector<ShadowModel> every_model() {
  std::vector<ShadowModel> models;
  models.reserve(size_t(ShadowModel::Count));
  for (int i = 0; i < int(ShadowModel::Count); ++i) models.push_back(ShadowModel(i));
  return models;
}

}  // namespace

TEST(ShadowModels, EveryModelHasItsRowAndWord) {
  EXPECT_EQ(penumbra::shadow_models().size(), size_t(ShadowModel::Count));
  for (ShadowModel m : every_model()) {
    SCOPED_TRACE(int(m));
    const penumbra::ShadowModelTraits& t = penumbra::shadow_model_traits(m);  // throws: no row
    EXPECT_EQ(t.value, m);
    EXPECT_EQ(penumbra::word(m), t.word);
    ShadowModel parsed = ShadowModel::Count;
    EXPECT_TRUE(penumbra::from_word(t.word, &parsed));
    EXPECT_EQ(parsed, m);
    EXPECT_GT(t.sigma_s, 0);
    EXPECT_GT(t.map_side, 0);
  }
  EXPECT_THROW(penumbra::shadow_model_traits(ShadowModel::Count), penumbra::Error);
}

TEST(ShadowModels, EveryModelHasItsPasses) {
  for (ShadowModel m : every_model()) {
    SCOPED_TRACE(penumbra::word(m));
    const penumbra::detail::ShadowModelPasses& row = penumbra::detail::shadow_model_passes(m);
    EXPECT_EQ(row.value, m);
    EXPECT_NE(row.lookup, nullptr);
    EXPECT_NE(row.lookup_backward, nullptr);
    EXPECT_NE(row.memory, nullptr);
    ASSERT_NE(row.lookup_file, nullptr);
    EXPECT_EQ(penumbra::detail::lookup_file_model(row.lookup_file), &row);
    if (row.light_map_needed != nullptr) {  // a light map comes with its stage and backward
      EXPECT_NE(row.light_map_stage, nullptr);
      EXPECT_NE(row.light_map, nullptr);
      EXPECT_NE(row.light_map_backward_texels, nullptr);
      EXPECT_NE(row.light_map_backward_faces, nullptr);
    }
  }
  EXPECT_THROW(penumbra::detail::shadow_model_passes(ShadowModel::Count), penumbra::Error);
}

// The tool's --shadow-model takes every model's word, and its help names each.
TEST(ShadowModels, TheToolTakesEveryWord) {
  const penumbra_tests::RunResult help = run_cli("render --help", "help");
  for (ShadowModel m : every_model())
    EXPECT_NE(help.out.find(penumbra::word(m) + " ("), std::string::npos) << penumbra::word(m);
  const penumbra_tests::RunResult bad = run_cli("render -o /dev/null --shadow-model bogus", "bad");
  EXPECT_EQ(bad.exit_code, 2);
  for (ShadowModel m : every_model())
    EXPECT_NE(bad.err.find(penumbra::word(m)), std::string::npos) << bad.err;
}
