// The tuning database: lookup falls back from the device to its processor model, its class and
// the heuristic; entries round-trip through files; the heuristic reacts to the workload.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "cli_run.hpp"
#include "penumbra/tuning.hpp"

using namespace penumbra;

TEST(Tuning, DatabaseFallsBackFromDeviceToClassToHeuristic) {
  const std::string path = ::testing::TempDir() + "/tuning_db.json";
  {
    std::ofstream out(path);
    out << R"({"version": 1, "entries": {
      "Exact Device 1": {"raster": {"tile": 32, "pixels_per_item": 4},
                         "exact": {"clblast": false, "vector_width": 16, "row_block": 2},
                         "penumbra": {"tile": 8}, "gather": {"group": 4, "width": 16}},
      "Acme/gpu": {"exact": {"clblast": true}, "soft_map": {"tile": 32}},
      "cpu": {"raster": {"pixels_per_item": 8}}}})";
  }
  const TuningDatabase db = TuningDatabase::load({path});
  EXPECT_EQ(db.size(), 3u);
  DeviceInfo dev;
  dev.max_work_group = 1024;
  WorkloadStats w;
  w.faces = 1000, w.mean_face_pixels = 20, w.cutoff_pixels = 1, w.width = w.height = 256;

  dev.name = "Exact Device 1", dev.vendor = "Acme", dev.is_gpu = true;
  Tuning t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "tuned:Exact Device 1");
  EXPECT_EQ(t.raster.tile, 32);
  EXPECT_EQ(t.raster.face_lanes, 32);  // not in the entry: a GPU's
  EXPECT_EQ(t.exact.vector_width, 16);
  EXPECT_EQ(t.soft_map.tile, 8);
  EXPECT_EQ(t.gather.group, 4);
  EXPECT_EQ(t.gather.width, 16);
  EXPECT_EQ(t.gather.height, 1);  // not in the entry: a GPU's

  dev.name = "Unknown Device 7";  // same vendor and type: the class entry, heuristic tile
  t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "heuristic+Acme/gpu");
  EXPECT_TRUE(t.exact.clblast);
  EXPECT_EQ(t.soft_map.tile, 32);
  EXPECT_EQ(t.raster.pixels_per_item, 1);  // the heuristic's choice for a GPU
  EXPECT_EQ(t.raster.face_lanes, 32);
  EXPECT_EQ(t.gather.group, 2);  // a GPU's
  EXPECT_EQ(t.gather.width, 4);
  EXPECT_EQ(t.gather.height, 1);

  // The statistics are asked for only where they decide: not with a tuned entry.
  int asked = 0;
  const auto counted = [&] {
    ++asked;
    return w;
  };
  EXPECT_EQ(db.lookup(dev, counted).source, "heuristic+Acme/gpu");
  EXPECT_EQ(asked, 1);
  dev.name = "Exact Device 1";
  EXPECT_EQ(db.lookup(dev, counted).source, "tuned:Exact Device 1");
  EXPECT_EQ(asked, 1);
  dev.name = "Unknown Device 7";

  dev.vendor = "Nobody", dev.is_gpu = false;  // only the type matches
  t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "heuristic+cpu");
  EXPECT_EQ(t.raster.pixels_per_item, 8);
  EXPECT_EQ(t.raster.face_lanes, 1);
  EXPECT_EQ(t.gather.group, 1);  // a CPU's
  EXPECT_EQ(t.gather.width, 8);
  EXPECT_EQ(t.gather.height, 8);

  const TuningDatabase empty = TuningDatabase::load({});
  t = empty.lookup(dev, w);
  EXPECT_EQ(t.source, "heuristic");
  EXPECT_NO_THROW(validate(t, dev));
}

// PoCL names a CPU by its model, with or without the clock ("... Processor @ 2.50GHz" on some
// machines of the same model): an entry for the model serves the name with a clock, and an
// entry for the exact name wins over it.
TEST(Tuning, ProcessorModelEntryServesTheNameWithAClock) {
  DeviceInfo dev;
  dev.max_work_group = 4096;
  for (const auto& [name, model] : std::vector<std::pair<std::string, std::string>>{
           {"Model CPU @ 2.50GHz", "Model CPU"},
           {"Model CPU@3.1 GHz", "Model CPU"},
           {"Model CPU @ 800MHz", "Model CPU"},
           {"Model CPU", "Model CPU"},
           {"Model @ CPU", "Model @ CPU"},
           {"Model CPU @ 2.50GHz rev 2", "Model CPU @ 2.50GHz rev 2"}}) {
    dev.name = name;
    EXPECT_EQ(TuningDatabase::model_key(dev), model) << name;
  }
  const std::string path = ::testing::TempDir() + "/tuning_model.json";
  {
    std::ofstream out(path);
    out << R"({"version": 1, "entries": {
      "Model CPU": {"raster": {"tile": 8, "pixels_per_item": 8}},
      "Model CPU @ 3.00GHz": {"raster": {"tile": 32, "pixels_per_item": 4}}}})";
  }
  const TuningDatabase db = TuningDatabase::load({path});
  WorkloadStats w;
  w.faces = 1000, w.mean_face_pixels = 20, w.cutoff_pixels = 1, w.width = w.height = 256;
  dev.name = "Model CPU @ 2.50GHz";
  Tuning t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "tuned:Model CPU");
  EXPECT_EQ(t.raster.tile, 8);
  dev.name = "Model CPU @ 3.00GHz";
  t = db.lookup(dev, w);
  EXPECT_EQ(t.source, "tuned:Model CPU @ 3.00GHz");
  EXPECT_EQ(t.raster.tile, 32);
  dev.name = "Other CPU @ 2.50GHz";
  EXPECT_EQ(db.lookup(dev, w).source, "heuristic");
  // The shipped database's Intel Xeon entry serves that model under both of PoCL's names
  // (no user cache or $PENUMBRA_TUNING here to override it).
  const penumbra_tests::ScopedEnv cache("XDG_CACHE_HOME",
                                        ::testing::TempDir() + "/tuning_no_cache");
  const penumbra_tests::ScopedEnv extra("PENUMBRA_TUNING", nullptr);
  dev.name = "pthread-skylake-avx512-Intel(R) Xeon(R) Processor @ 2.50GHz";
  EXPECT_EQ(TuningDatabase::load_default().lookup(dev, w).source,
            "tuned:pthread-skylake-avx512-Intel(R) Xeon(R) Processor");
}

TEST(Tuning, HeuristicPrefersSmallTilesForManySmallFaces) {
  DeviceInfo cpu;
  cpu.max_work_group = 4096;
  WorkloadStats many_small;
  many_small.faces = 200000, many_small.mean_face_pixels = 1, many_small.cutoff_pixels = 1;
  many_small.width = many_small.height = 1024;
  WorkloadStats few_large = many_small;
  few_large.faces = 50, few_large.mean_face_pixels = 20000;
  const Tuning a = heuristic_tuning(cpu, many_small), b = heuristic_tuning(cpu, few_large);
  EXPECT_LT(a.raster.tile, b.raster.tile);
  EXPECT_EQ(a.raster.pixels_per_item, 8);
  DeviceInfo gpu = cpu;
  gpu.is_gpu = true;
  gpu.max_work_group = 1024;
  EXPECT_EQ(heuristic_tuning(gpu, few_large).raster.pixels_per_item, 1);
}

TEST(Tuning, DatabaseRoundTripsClblastParametersAndReadsOldEntries) {
  const std::string path = ::testing::TempDir() + "/tuning_xgemm.json";
  DeviceInfo dev;
  dev.name = "Exact Device 2", dev.vendor = "Acme", dev.max_work_group = 1024;
  Tuning t;
  t.raster.pixels_per_item = 8;
  t.exact.clblast = true;
  t.exact.xgemm = xgemm_candidates(false).back();
  t.exact.xgemm->KWI = 8;  // differs from every default
  t.exact.min_indirect_size = 1;
  t.gather = {2, 16, 4};
  TuningDatabase db = TuningDatabase::load({});
  db.set(dev.name, t);
  db.save(path);
  Tuning back = TuningDatabase::load({path}).lookup(dev, WorkloadStats{});
  EXPECT_EQ(back.gather.group, 2);
  EXPECT_EQ(back.gather.width, 16);
  EXPECT_EQ(back.gather.height, 4);
  ASSERT_TRUE(back.exact.xgemm.has_value());
  EXPECT_EQ(*back.exact.xgemm, *t.exact.xgemm) << back.exact.xgemm->describe();
  EXPECT_EQ(back.exact.xgemm->KWI, 8);
  EXPECT_EQ(back.exact.min_indirect_size, 1);
  EXPECT_TRUE(back.exact.clblast);

  // A database written before these fields existed: CLBlast's own parameters.
  {
    std::ofstream out(path);
    out << R"({"version": 1, "entries": {"Exact Device 2":
      {"raster": {"pixels_per_item": 8},
       "exact": {"clblast": true, "vector_width": 4, "row_block": 2}}}})";
  }
  back = TuningDatabase::load({path}).lookup(dev, WorkloadStats{});
  EXPECT_FALSE(back.exact.xgemm.has_value());
  EXPECT_EQ(back.exact.min_indirect_size, 0);
  EXPECT_EQ(back.exact.vector_width, 4);

  // An incomplete set is refused with a warning naming the missing parameter.
  {
    std::ofstream out(path);
    out << R"({"version": 1, "entries": {"Exact Device 2":
      {"exact": {"clblast": true, "xgemm": {"MWG": 64, "NWG": 64}}}}})";
  }
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(TuningDatabase::load({path}).size(), 0u);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("\"xgemm\" lacks GEMMK"), std::string::npos) << err;
}
