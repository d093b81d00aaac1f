#pragma once

// The scan store: every scan as an .mscan archive (docs/scan-format.md) under the device's
// --data-dir, with a small JSON metadata file beside it.
//
//   <id>.mscan.partial   the archive while it is written (and after a crash: kept)
//   <id>.mscan           the archive after Finish
//   <id>.json            metadata, always replaced atomically (temp, fsync, rename, fsync dir)
//   <id>.json.tmp        a metadata write in progress; removed by Open
//   <id>.results/<name>  the host's processed results (protocol::ResultKinds: mesh.ply,
//                        previews, measurements.json, summary.json), each replaced
//                        atomically; deleted with the scan
//   <id>.results/<name>.tmp-N  an upload in progress; removed by Open (as is a results
//                        folder whose scan is gone)
//
// States in the metadata: "writing" (a handle is open), "complete", "aborted", "fault"
// (finished archives: the footer's status), "partial" (never finished: a crash, an
// abandoned handle or a write error; the reason is the reader's recovery report).
// Partial archives count towards the retention limit like finished ones.
// Metadata that cannot be written (disk full) is kept in memory and reported from there,
// so opening a store and ending a scan never need free space; problem() says so.
//
// Thread-safe: one ScanStore may serve the sequencer and the HTTP threads at once. A
// ScanHandle is used by one thread at a time.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/scan_format/scan_format.h"

namespace mirrorscan::store {

// Every store failure. kIo (disk full, EIO, permissions) during a scan is what the
// sequencer turns into a fault; the other kinds map to HTTP 400/404/409.
class StoreError : public std::runtime_error {
 public:
  enum class Kind {
    kIo,               // a file operation failed; the message names the file and errno
    kInvalidId,        // not a scan id (IsValidScanId); nothing was touched
    kNotFound,         // no scan with that id
    kBusy,             // the scan is being written
    kInvalidArgument,  // e.g. a header that is not a JSON object, an unknown footer status
  };
  StoreError(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

// "YYYYMMDDTHHMMSSZ-NNNN" (UTC start time, then a counter): exactly 21 ASCII characters,
// digits where digits go. Ids sort in the order the scans were begun.
bool IsValidScanId(std::string_view id);

enum class ScanState { kWriting, kComplete, kAborted, kFault, kPartial };
std::string_view ScanStateName(ScanState state);  // "writing", "complete", ...

struct ScanInfo {
  std::string id;
  ScanState state = ScanState::kWriting;
  std::string reason;  // footer reason (aborted/fault) or recovery report (partial)
  uint64_t frames = 0;
  uint64_t peaks = 0;
  uint64_t bytes = 0;     // archive size
  std::string created;    // UTC, "2026-11-24T02:55:01Z"
  nlohmann::json header;  // the archive header (object), as given to BeginScan
  nlohmann::json footer;  // null unless finished

  nlohmann::json ToJson() const;  // the metadata file's content
};

struct ScanStoreOptions {
  uint32_t fsync_every_frames = 30;  // 0: only on Finish
  // Keep at most this many stored scans (complete, aborted, fault or crash-partial),
  // deleting the oldest after each Finish and on Open. 0: keep all. The scan being
  // written is never counted or deleted.
  size_t keep_finished = 0;
  // Wall clock for ids and "created"; tests inject one. Null: system_clock::now.
  std::function<std::chrono::system_clock::time_point()> now;
};

namespace internal {
struct StoreState;
}

// A stored result of a scan.
struct StoredResult {
  std::string name;
  uint64_t bytes = 0;
  std::filesystem::file_time_type modified;
};

// One result being uploaded into a temp file beside the others. Destroying it without
// Commit removes the temp file; the stored result (if any) is untouched until Commit.
class ResultUpload {
 public:
  ~ResultUpload();
  ResultUpload(const ResultUpload&) = delete;
  ResultUpload& operator=(const ResultUpload&) = delete;

  void Append(const char* data, size_t size);  // kIo (disk full: the upload is failed)
  // fsync, rename over <id>.results/<name>, fsync the folder. kNotFound when the scan was
  // deleted meanwhile, kIo.
  void Commit();
  uint64_t bytes() const { return bytes_; }

 private:
  friend class ScanStore;
  ResultUpload(std::shared_ptr<internal::StoreState> state, std::string id, std::string name,
               std::filesystem::path temp, int fd);

  std::shared_ptr<internal::StoreState> state_;
  std::string id_;
  std::string name_;
  std::filesystem::path temp_;
  int fd_;
  uint64_t bytes_ = 0;
  bool committed_ = false;
};

// One scan being written. Destroying it without Finish (or after an error) keeps the
// .partial archive and marks it "partial" with the recovery report, best effort; a real
// crash leaves the same for the next Open to mark.
class ScanHandle {
 public:
  ~ScanHandle();
  ScanHandle(const ScanHandle&) = delete;
  ScanHandle& operator=(const ScanHandle&) = delete;

  const std::string& id() const { return id_; }
  // StoreError kIo on a write error; the handle is then failed and only destruction is left.
  void AppendFrame(const FrameRecord& frame);
  // footer["status"] is "complete" (default when absent), "aborted" or "fault"; "reason"
  // is copied to the metadata. fsyncs, renames .partial to .mscan, fsyncs the directory,
  // writes the metadata, then applies the retention limit.
  void Finish(const nlohmann::json& footer);

  uint64_t frames() const { return frames_; }
  uint64_t peaks() const { return peaks_; }
  uint64_t bytes() const { return bytes_; }

 private:
  friend class ScanStore;
  ScanHandle(std::shared_ptr<internal::StoreState> state, ScanInfo info,
             std::unique_ptr<ScanFileWriter> writer);
  // Leaves the active set, saving `info` (kept in memory when the disk is full) first.
  void Close(std::optional<ScanInfo> info) noexcept;

  std::shared_ptr<internal::StoreState> state_;
  std::string id_;
  ScanInfo info_;
  std::unique_ptr<ScanFileWriter> writer_;
  bool failed_ = false;
  bool closed_ = false;
  std::atomic<uint64_t> frames_{0};
  std::atomic<uint64_t> peaks_{0};
  std::atomic<uint64_t> bytes_{0};
};

class ScanStore {
 public:
  // Creates dir if needed; removes leftover temp files and metadata whose archive is gone;
  // marks every .partial archive (and any archive without usable metadata) from what
  // ReadScanFile recovers; applies the retention limit. Throws StoreError kIo.
  static std::unique_ptr<ScanStore> Open(const std::filesystem::path& dir,
                                         ScanStoreOptions options = {});
  ~ScanStore();

  // A new scan: creates <id>.mscan.partial with the header (plus "scan_id": id) and the
  // metadata in state "writing". kInvalidArgument when header is not an object, kIo.
  std::unique_ptr<ScanHandle> BeginScan(const nlohmann::json& header);

  std::vector<ScanInfo> List() const;         // newest first; live counters while writing
  ScanInfo Get(const std::string& id) const;  // kInvalidId, kNotFound
  // The archive to download: .mscan, or .mscan.partial while writing or after a crash.
  std::filesystem::path Path(const std::string& id) const;
  // Removes archive, metadata and results. kBusy while the scan is being written.
  void Delete(const std::string& id);

  // Starts storing result `name` (protocol::FindResultKind) of a finished scan.
  // kInvalidId, kInvalidArgument for a name not on the list, kNotFound, kBusy while the
  // scan is being written, kIo.
  std::unique_ptr<ResultUpload> BeginResult(const std::string& id, const std::string& name);
  // The scan's stored results, in protocol::ResultKinds order. kInvalidId, kNotFound.
  std::vector<StoredResult> Results(const std::string& id) const;
  // The file of one stored result. kInvalidId, kInvalidArgument, kNotFound.
  std::filesystem::path ResultPath(const std::string& id, const std::string& name) const;

  const std::filesystem::path& dir() const;
  // Empty, or why some metadata lives only in memory (the disk was full); retried after
  // each Delete.
  std::string problem() const;

 private:
  explicit ScanStore(std::shared_ptr<internal::StoreState> state);
  std::shared_ptr<internal::StoreState> state_;
};

}  // namespace mirrorscan::store
