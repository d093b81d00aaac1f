#include "firmware/store/scan_store.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace mirrorscan::store {
namespace {

namespace fs = std::filesystem;

class ScanStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("mirrorscan_store_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static FrameRecord Frame(uint32_t seq, size_t peaks) {
    FrameRecord f;
    f.sequence = seq;
    f.timestamp_ns = 1000 * static_cast<int64_t>(seq);
    f.lasers_on = true;
    for (size_t i = 0; i < peaks; ++i) {
      Peak p;
      p.u = static_cast<uint16_t>(i);
      p.v = 10.5f;
      f.peaks.push_back(p);
    }
    return f;
  }

  // A finished scan of `frames` frames with 3 peaks each; returns its id.
  static std::string WriteScan(ScanStore& store, int frames,
                               const std::string& status = "complete") {
    auto h = store.BeginScan({{"device", "test"}});
    for (int i = 0; i < frames; ++i) h->AppendFrame(Frame(i, 3));
    h->Finish({{"status", status}, {"reason", status == "complete" ? "" : "button pressed"}});
    return h->id();
  }

  fs::path dir_;
};

TEST(ScanIdTest, AcceptsOnlyTheStrictFormat) {
  EXPECT_TRUE(IsValidScanId("20261124T025501Z-0001"));
  EXPECT_TRUE(IsValidScanId("19700101T000000Z-9999"));
  const std::vector<std::string> bad_ids = {"",
                                            "../x",
                                            "../61124T025501Z-0001",
                                            "2026/124T025501Z-0001",
                                            "a/b",
                                            "20261124T025501Z-0001/../../etc",
                                            "../0261124T025501Z-0001",
                                            "20261124T025501Z-001",
                                            "20261124T025501Z-00001",
                                            "20261124t025501Z-0001",
                                            "20261124T025501Z_0001",
                                            "2026112aT025501Z-0001",
                                            "20261124T025501Z-0001 ",
                                            "20261124T02550\xc3\xa9Z-0001",
                                            std::string(4096, '1'),
                                            std::string("20261124T025501Z-000\0", 21)};
  for (const std::string& bad : bad_ids) {
    EXPECT_FALSE(IsValidScanId(bad)) << bad;
  }
}

TEST_F(ScanStoreTest, CompleteScanRoundTrip) {
  auto store = ScanStore::Open(dir_);
  auto h = store->BeginScan({{"device", "test"}, {"lasers", 3}});
  const std::string id = h->id();
  EXPECT_TRUE(IsValidScanId(id)) << id;
  EXPECT_TRUE(fs::exists(dir_ / (id + ".mscan.partial")));
  for (int i = 0; i < 10; ++i) h->AppendFrame(Frame(i, 4));
  {
    const auto list = store->List();
    ASSERT_EQ(list.size(), 1u);
    EXPECT_EQ(list[0].state, ScanState::kWriting);
    EXPECT_EQ(list[0].frames, 10u);
    EXPECT_EQ(store->Path(id), dir_ / (id + ".mscan.partial"));
  }
  h->Finish({{"status", "complete"}, {"frames", 10}});
  EXPECT_FALSE(fs::exists(dir_ / (id + ".mscan.partial")));
  ASSERT_EQ(store->Path(id), dir_ / (id + ".mscan"));

  const ScanInfo info = store->Get(id);
  EXPECT_EQ(info.state, ScanState::kComplete);
  EXPECT_EQ(info.frames, 10u);
  EXPECT_EQ(info.peaks, 40u);
  EXPECT_EQ(info.bytes, fs::file_size(store->Path(id)));
  EXPECT_EQ(info.header["scan_id"], id);
  EXPECT_EQ(info.created.size(), 20u);

  const ScanArchive archive = ReadScanFile(store->Path(id));
  EXPECT_TRUE(archive.report.complete) << archive.report.message;
  EXPECT_EQ(archive.frames.size(), 10u);
  EXPECT_EQ(archive.header["lasers"], 3);

  // The metadata file says the same, and survives a reopen unchanged.
  std::ifstream meta(dir_ / (id + ".json"));
  const auto j = nlohmann::json::parse(meta);
  EXPECT_EQ(j["state"], "complete");
  EXPECT_EQ(j["frames"], 10);
  store.reset();
  store = ScanStore::Open(dir_);
  EXPECT_EQ(store->Get(id).state, ScanState::kComplete);
  EXPECT_EQ(store->Get(id).peaks, 40u);
}

TEST_F(ScanStoreTest, AbortedAndFaultScansKeepTheirReason) {
  auto store = ScanStore::Open(dir_);
  const std::string a = WriteScan(*store, 2, "aborted");
  const std::string f = WriteScan(*store, 1, "fault");
  EXPECT_EQ(store->Get(a).state, ScanState::kAborted);
  EXPECT_EQ(store->Get(a).reason, "button pressed");
  EXPECT_EQ(store->Get(f).state, ScanState::kFault);
  auto h = store->BeginScan(nlohmann::json::object());
  EXPECT_THROW(h->Finish({{"status", "bogus"}}), StoreError);
  EXPECT_THROW(store->BeginScan(nlohmann::json::array()), StoreError);
  h->Finish(nlohmann::json::object());  // status defaults to complete
  EXPECT_EQ(store->Get(h->id()).state, ScanState::kComplete);
}

TEST_F(ScanStoreTest, IdsAreTimeSortableAndNeverGoBackwards) {
  auto t = std::chrono::system_clock::from_time_t(1795000000);
  ScanStoreOptions options;
  options.now = [&t] { return t; };
  auto store = ScanStore::Open(dir_, options);
  const std::string a = WriteScan(*store, 0);
  const std::string b = WriteScan(*store, 0);  // same second
  t -= std::chrono::hours(24 * 365);           // clock set back (no RTC)
  const std::string c = WriteScan(*store, 0);
  EXPECT_LT(a, b);
  EXPECT_LT(b, c);
  EXPECT_EQ(a.substr(0, 16), b.substr(0, 16));
  EXPECT_EQ(b.substr(17), "0002");
  // Newest first.
  const auto list = store->List();
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[0].id, c);
  EXPECT_EQ(list[2].id, a);
  // A reopened store continues after the newest id on disk.
  store = ScanStore::Open(dir_, options);
  EXPECT_LT(c, WriteScan(*store, 0));
}

TEST_F(ScanStoreTest, CrashInAChildLeavesAPartialScanThatReopenMarks) {
  std::string earlier;
  {
    auto store = ScanStore::Open(dir_);
    earlier = WriteScan(*store, 5);
  }
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ScanStoreOptions options;
    options.fsync_every_frames = 1;
    auto store = ScanStore::Open(dir_, options);
    auto h = store->BeginScan({{"device", "crash"}});
    for (int i = 0; i < 7; ++i) h->AppendFrame(Frame(i, 2));
    ::_exit(0);  // no destructors, no Finish: as a crash
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  // Garbage after the last record, as a cut-off write would leave, and a stray temp file.
  fs::path partial;
  for (const auto& e : fs::directory_iterator(dir_)) {
    if (e.path().string().ends_with(".mscan.partial")) partial = e.path();
  }
  ASSERT_FALSE(partial.empty());
  { std::ofstream(partial, std::ios::app | std::ios::binary) << "\x02\x00\x00\x00garbage"; }
  { std::ofstream(dir_ / "20261124T025501Z-0009.json.tmp") << "{"; }

  auto store = ScanStore::Open(dir_);
  EXPECT_FALSE(fs::exists(dir_ / "20261124T025501Z-0009.json.tmp"));
  EXPECT_TRUE(fs::exists(partial));  // kept, never deleted
  const auto list = store->List();
  ASSERT_EQ(list.size(), 2u);
  const ScanInfo& p = list[0];
  EXPECT_EQ(p.state, ScanState::kPartial);
  EXPECT_EQ(p.frames, 7u);
  EXPECT_EQ(p.peaks, 14u);
  EXPECT_NE(p.reason.find("recovered 7 frames"), std::string::npos) << p.reason;
  EXPECT_EQ(p.header["device"], "crash");
  EXPECT_EQ(store->Path(p.id), partial);
  // The earlier scan is intact.
  EXPECT_EQ(list[1].id, earlier);
  EXPECT_EQ(list[1].state, ScanState::kComplete);
  const ScanArchive archive = ReadScanFile(store->Path(earlier));
  EXPECT_TRUE(archive.report.complete);
  EXPECT_EQ(archive.frames.size(), 5u);
  // New scans still get later ids.
  EXPECT_LT(p.id, WriteScan(*store, 1));
}

TEST_F(ScanStoreTest, AbandonedHandleIsMarkedPartial) {
  auto store = ScanStore::Open(dir_);
  std::string id;
  {
    auto h = store->BeginScan({{"device", "test"}});
    id = h->id();
    for (int i = 0; i < 3; ++i) h->AppendFrame(Frame(i, 1));
  }  // destroyed without Finish
  const ScanInfo info = store->Get(id);
  EXPECT_EQ(info.state, ScanState::kPartial);
  EXPECT_EQ(info.frames, 3u);
  EXPECT_NE(info.reason.find("recovered 3 frames"), std::string::npos) << info.reason;
  EXPECT_NO_THROW(store->Delete(id));  // no longer being written
}

TEST_F(ScanStoreTest, CrashBetweenRenameAndMetadataIsRecovered) {
  auto store = ScanStore::Open(dir_);
  auto h = store->BeginScan({{"device", "test"}});
  const std::string id = h->id();
  const auto writing_meta = [&] {
    std::ifstream in(dir_ / (id + ".json"));
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  }();
  h->AppendFrame(Frame(0, 2));
  h->Finish({{"status", "aborted"}, {"reason", "stop"}});
  std::ofstream(dir_ / (id + ".json")) << writing_meta;  // metadata still "writing"
  store = ScanStore::Open(dir_);
  const ScanInfo info = store->Get(id);
  EXPECT_EQ(info.state, ScanState::kAborted);
  EXPECT_EQ(info.reason, "stop");
  EXPECT_EQ(info.frames, 1u);
}

TEST_F(ScanStoreTest, RetentionKeepsTheNewestStoredScansPartialOnesIncluded) {
  ScanStoreOptions options;
  options.keep_finished = 2;
  auto store = ScanStore::Open(dir_, options);
  const std::string s1 = WriteScan(*store, 1);
  std::string partial;
  {
    auto h = store->BeginScan({{"device", "test"}});
    partial = h->id();
    h->AppendFrame(Frame(0, 1));
  }
  auto writing = store->BeginScan({{"device", "test"}});
  const std::string s2 = WriteScan(*store, 1, "aborted");
  const std::string s3 = WriteScan(*store, 1);
  const std::string s4 = WriteScan(*store, 1);
  // A crash-partial counts like a finished scan (it is as personal and as large).
  for (const std::string& gone : {s1, partial, s2}) {
    EXPECT_THROW(store->Get(gone), StoreError) << gone;
  }
  EXPECT_FALSE(fs::exists(dir_ / (s1 + ".mscan")));
  EXPECT_FALSE(fs::exists(dir_ / (partial + ".mscan.partial")));
  EXPECT_EQ(store->Get(s3).state, ScanState::kComplete);
  EXPECT_EQ(store->Get(s4).state, ScanState::kComplete);
  // The scan being written is never counted or removed.
  EXPECT_EQ(store->Get(writing->id()).state, ScanState::kWriting);
  writing->Finish(nlohmann::json::object());  // older than s3 and s4 once finished: goes
  EXPECT_THROW(store->Get(writing->id()), StoreError);
  EXPECT_EQ(store->List().size(), 2u);

  // Retention also applies on Open with a smaller limit.
  options.keep_finished = 1;
  store = ScanStore::Open(dir_, options);
  const auto list = store->List();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].id, s4);
}

TEST_F(ScanStoreTest, APartialWhoseBytesChangedButNotItsSizeIsReadAgainAtOpen) {
  std::string id;
  {
    auto store = ScanStore::Open(dir_);
    auto h = store->BeginScan({{"device", "test"}});
    id = h->id();
    for (uint32_t i = 0; i < 40; ++i) h->AppendFrame(Frame(i, 50));
  }  // abandoned: partial, 40 frames
  ASSERT_EQ(ScanStore::Open(dir_)->Get(id).frames, 40u);
  // Flip one bit in the middle of the archive: same size, fewer readable frames.
  const fs::path path = dir_ / (id + ".mscan.partial");
  const auto size = fs::file_size(path);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(size / 2));
    char byte = 0;
    f.read(&byte, 1);
    byte = static_cast<char>(byte ^ 0x10);
    f.seekp(static_cast<std::streamoff>(size / 2));
    f.write(&byte, 1);
  }
  ASSERT_EQ(fs::file_size(path), size);
  const ScanInfo reread = ScanStore::Open(dir_)->Get(id);
  EXPECT_EQ(reread.state, ScanState::kPartial);
  EXPECT_LT(reread.frames, 40u);
  EXPECT_GT(reread.frames, 5u);
}

TEST_F(ScanStoreTest, DeleteChecksIdAndRefusesTheScanBeingWritten) {
  auto store = ScanStore::Open(dir_);
  const std::string done = WriteScan(*store, 1);
  auto h = store->BeginScan({{"device", "test"}});
  try {
    store->Delete(h->id());
    FAIL() << "deleted a scan being written";
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kBusy);
  }
  EXPECT_TRUE(fs::exists(store->Path(h->id())));
  for (const std::string bad : {"../x", "a/b", "", "../../etc/passwd"}) {
    try {
      store->Delete(bad);
      FAIL() << bad;
    } catch (const StoreError& e) {
      EXPECT_EQ(e.kind(), StoreError::Kind::kInvalidId) << bad;
    }
    EXPECT_THROW(store->Get(bad), StoreError);
    EXPECT_THROW(store->Path(bad), StoreError);
  }
  try {
    store->Delete("20000101T000000Z-0001");
    FAIL();
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kNotFound);
  }
  store->Delete(done);
  EXPECT_FALSE(fs::exists(dir_ / (done + ".mscan")));
  EXPECT_FALSE(fs::exists(dir_ / (done + ".json")));
  EXPECT_THROW(store->Get(done), StoreError);
  h->Finish(nlohmann::json::object());
  EXPECT_EQ(store->List().size(), 1u);
}

// Disk full, bounded: a forked child with a file-size limit (SIGXFSZ ignored, so write
// fails with EFBIG) must see a StoreError kIo, not a crash.
TEST_F(ScanStoreTest, WriteErrorIsAStoreErrorAndEarlierScansSurvive) {
  std::string earlier;
  {
    auto store = ScanStore::Open(dir_);
    earlier = WriteScan(*store, 20);
  }
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit{64 * 1024, 64 * 1024};
    if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) ::_exit(2);
    int code = 1;
    try {
      auto store = ScanStore::Open(dir_);
      auto h = store->BeginScan({{"device", "full"}});
      for (int i = 0; i < 1000; ++i) h->AppendFrame(Frame(i, 100));  // ~1.8 MB
      h->Finish(nlohmann::json::object());
    } catch (const StoreError& e) {
      code = e.kind() == StoreError::Kind::kIo &&
                     std::string(e.what()).find("write") != std::string::npos
                 ? 42
                 : 3;
    } catch (...) {
      code = 4;
    }
    ::_exit(code);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "child died of signal " << WTERMSIG(status);
  ASSERT_EQ(WEXITSTATUS(status), 42);

  auto store = ScanStore::Open(dir_);
  const auto list = store->List();
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].state, ScanState::kPartial);
  EXPECT_GT(list[0].frames, 0u);
  EXPECT_LE(list[0].bytes, 64u * 1024);
  EXPECT_EQ(list[1].id, earlier);
  const ScanArchive archive = ReadScanFile(store->Path(earlier));
  EXPECT_TRUE(archive.report.complete);
  EXPECT_EQ(archive.frames.size(), 20u);
}

TEST_F(ScanStoreTest, OrphanMetadataIsRemovedAndArchivesWithoutMetadataAreListed) {
  std::string id;
  {
    auto store = ScanStore::Open(dir_);
    id = WriteScan(*store, 2);
  }
  fs::remove(dir_ / (id + ".json"));
  { std::ofstream(dir_ / "20000101T000000Z-0001.json") << R"({"id":"x"})"; }
  { std::ofstream(dir_ / "notes.txt") << "left alone"; }
  auto store = ScanStore::Open(dir_);
  EXPECT_FALSE(fs::exists(dir_ / "20000101T000000Z-0001.json"));
  EXPECT_TRUE(fs::exists(dir_ / "notes.txt"));
  const ScanInfo info = store->Get(id);
  EXPECT_EQ(info.state, ScanState::kComplete);
  EXPECT_EQ(info.frames, 2u);
}

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void PutResult(ScanStore& store, const std::string& id, const std::string& name,
               const std::string& content) {
  auto upload = store.BeginResult(id, name);
  // In two pieces, as the server appends what arrives.
  upload->Append(content.data(), content.size() / 2);
  upload->Append(content.data() + content.size() / 2, content.size() - content.size() / 2);
  upload->Commit();
}

TEST_F(ScanStoreTest, ResultsAreStoredBesideTheScanListedAndReplacedWhole) {
  auto store = ScanStore::Open(dir_);
  const std::string id = WriteScan(*store, 2);
  EXPECT_TRUE(store->Results(id).empty());
  PutResult(*store, id, "summary.json", R"({"ok": true})");
  PutResult(*store, id, "mesh.ply", std::string(100000, 'm'));
  const std::vector<StoredResult> results = store->Results(id);
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].name, "mesh.ply");  // protocol::ResultKinds order
  EXPECT_EQ(results[0].bytes, 100000u);
  EXPECT_EQ(results[1].name, "summary.json");
  EXPECT_EQ(store->ResultPath(id, "mesh.ply"), dir_ / (id + ".results") / "mesh.ply");
  EXPECT_EQ(ReadAll(store->ResultPath(id, "summary.json")), R"({"ok": true})");

  // An upload in progress leaves the stored file as it was; a dropped one leaves nothing.
  {
    auto upload = store->BeginResult(id, "summary.json");
    upload->Append("{\"ok\"", 5);
    EXPECT_EQ(ReadAll(store->ResultPath(id, "summary.json")), R"({"ok": true})");
  }
  EXPECT_EQ(ReadAll(store->ResultPath(id, "summary.json")), R"({"ok": true})");
  PutResult(*store, id, "summary.json", R"({"ok": false})");
  EXPECT_EQ(ReadAll(store->ResultPath(id, "summary.json")), R"({"ok": false})");
  size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir_ / (id + ".results"))) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 2u);  // no temp files left
}

TEST_F(ScanStoreTest, ResultNamesAreAFixedListAndScansMustBeFinished) {
  auto store = ScanStore::Open(dir_);
  const std::string id = WriteScan(*store, 1);
  for (const char* bad :
       {"points.ply", "../x.json", "mesh.ply/", "", "MESH.PLY", "summary.json.tmp-1", "mesh.obj"}) {
    try {
      store->BeginResult(id, bad);
      ADD_FAILURE() << bad;
    } catch (const StoreError& e) {
      EXPECT_EQ(e.kind(), StoreError::Kind::kInvalidArgument) << bad;
    }
  }
  try {
    store->BeginResult("../" + id, "mesh.ply");
    ADD_FAILURE();
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kInvalidId);
  }
  try {
    store->BeginResult("20000101T000000Z-0001", "mesh.ply");
    ADD_FAILURE();
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kNotFound);
  }
  auto writing = store->BeginScan({{"device", "test"}});
  try {
    store->BeginResult(writing->id(), "mesh.ply");
    ADD_FAILURE();
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kBusy);
  }
  try {
    store->ResultPath(id, "mesh.ply");
    ADD_FAILURE();
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kNotFound);
  }
  EXPECT_FALSE(fs::exists(dir_ / (writing->id() + ".results")));
}

TEST_F(ScanStoreTest, ResultsGoWithTheScanAndAnUploadRacingADeleteFails) {
  auto store = ScanStore::Open(dir_);
  const std::string id = WriteScan(*store, 1);
  PutResult(*store, id, "mesh.ply", "ply");
  auto late = store->BeginResult(id, "summary.json");
  late->Append("{}", 2);
  store->Delete(id);
  EXPECT_FALSE(fs::exists(dir_ / (id + ".results")));
  try {
    late->Commit();
    ADD_FAILURE();
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind(), StoreError::Kind::kNotFound);
  }
  EXPECT_FALSE(fs::exists(dir_ / (id + ".results")));
}

TEST_F(ScanStoreTest, OpenRemovesOrphanResultsAndUnfinishedUploads) {
  std::string kept, deleted;
  {
    auto store = ScanStore::Open(dir_);
    kept = WriteScan(*store, 1);
    deleted = WriteScan(*store, 1);
    PutResult(*store, kept, "mesh.ply", "ply");
    PutResult(*store, deleted, "mesh.ply", "ply");
  }
  // A deletion cut short after the archive went; an upload cut short by a crash.
  fs::remove(dir_ / (deleted + ".mscan"));
  fs::remove(dir_ / (deleted + ".json"));
  { std::ofstream(dir_ / (kept + ".results") / "summary.json.tmp-7") << "{"; }
  auto store = ScanStore::Open(dir_);
  EXPECT_FALSE(fs::exists(dir_ / (deleted + ".results")));
  EXPECT_FALSE(fs::exists(dir_ / (kept + ".results") / "summary.json.tmp-7"));
  EXPECT_EQ(ReadAll(store->ResultPath(kept, "mesh.ply")), "ply");
}

TEST_F(ScanStoreTest, RetentionTakesTheResultsWithTheScan) {
  ScanStoreOptions options;
  options.keep_finished = 1;
  auto store = ScanStore::Open(dir_, options);
  const std::string old_id = WriteScan(*store, 1);
  PutResult(*store, old_id, "mesh.ply", "ply");
  WriteScan(*store, 1);
  EXPECT_FALSE(fs::exists(dir_ / (old_id + ".results")));
}

}  // namespace
}  // namespace mirrorscan::store
