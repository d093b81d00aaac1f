#include "firmware/store/scan_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <system_error>
#include <utility>

#include "common/protocol/protocol.h"

namespace mirrorscan::store {

namespace fs = std::filesystem;

namespace internal {

struct StoreState {
  fs::path dir;
  ScanStoreOptions options;
  mutable std::mutex mu;
  std::map<std::string, ScanHandle*> active;  // guarded by mu
  std::string last_id;                        // guarded by mu
  // Metadata that could not be written (disk full): what Get and List report until a
  // write succeeds. Guarded by mu.
  std::map<std::string, ScanInfo> unsaved;
  std::string unsaved_error;  // the last such write's error
  uint64_t next_upload = 0;   // guarded by mu; makes concurrent uploads' temp names differ
};

}  // namespace internal

namespace {

constexpr std::string_view kArchiveSuffix = ".mscan";
constexpr std::string_view kPartialSuffix = ".mscan.partial";
constexpr std::string_view kMetaSuffix = ".json";
constexpr std::string_view kTmpSuffix = ".json.tmp";
constexpr std::string_view kResultsSuffix = ".results";
constexpr std::string_view kUploadInfix = ".tmp-";

fs::path ArchivePath(const fs::path& dir, const std::string& id) {
  return dir / (id + std::string(kArchiveSuffix));
}
fs::path PartialPath(const fs::path& dir, const std::string& id) {
  return dir / (id + std::string(kPartialSuffix));
}
fs::path MetaPath(const fs::path& dir, const std::string& id) {
  return dir / (id + std::string(kMetaSuffix));
}
fs::path ResultsDir(const fs::path& dir, const std::string& id) {
  return dir / (id + std::string(kResultsSuffix));
}

[[noreturn]] void ThrowIo(const fs::path& path, const std::string& what, int err = errno) {
  throw StoreError(StoreError::Kind::kIo, path.string() + ": " + what + ": " + std::strerror(err));
}

void SyncDir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) ThrowIo(dir, "cannot open directory to sync it");
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (rc != 0) ThrowIo(dir, "fsync", err);
}

// temp file, write, fsync, rename over path, fsync the directory.
void WriteFileAtomically(const fs::path& path, const std::string& content) {
  const fs::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) ThrowIo(tmp, "cannot create");
  auto fail = [&](const char* what) {
    const int err = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    ThrowIo(tmp, what, err);
  };
  const char* data = content.data();
  size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write");
    }
    data += n;
    left -= static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) fail("fsync");
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    ThrowIo(tmp, "close", err);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    ThrowIo(path, "rename", err);
  }
  SyncDir(path.parent_path());
}

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

std::optional<ScanState> ParseState(std::string_view name) {
  for (ScanState s : {ScanState::kWriting, ScanState::kComplete, ScanState::kAborted,
                      ScanState::kFault, ScanState::kPartial}) {
    if (ScanStateName(s) == name) return s;
  }
  return std::nullopt;
}

bool IsFinished(ScanState s) {
  return s == ScanState::kComplete || s == ScanState::kAborted || s == ScanState::kFault;
}

// "20261124T025501Z-0001" -> "2026-11-24T02:55:01Z"
std::string CreatedFromId(const std::string& id) {
  return id.substr(0, 4) + "-" + id.substr(4, 2) + "-" + id.substr(6, 2) + "T" + id.substr(9, 2) +
         ":" + id.substr(11, 2) + ":" + id.substr(13, 2) + "Z";
}

std::string FormatStamp(std::time_t t) {
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y%m%dT%H%M%SZ", &tm);
  return buf;
}

std::time_t ParseStamp(const std::string& stamp) {
  std::tm tm{};
  tm.tm_year = std::stoi(stamp.substr(0, 4)) - 1900;
  tm.tm_mon = std::stoi(stamp.substr(4, 2)) - 1;
  tm.tm_mday = std::stoi(stamp.substr(6, 2));
  tm.tm_hour = std::stoi(stamp.substr(9, 2));
  tm.tm_min = std::stoi(stamp.substr(11, 2));
  tm.tm_sec = std::stoi(stamp.substr(13, 2));
  return timegm(&tm);
}

// The next id: the current second, or (when the clock is behind the newest id, e.g. a
// board without RTC) the newest id's second with the counter advanced, so ids never
// go backwards.
std::string NextId(const internal::StoreState& state) {
  const auto now = state.options.now ? state.options.now() : std::chrono::system_clock::now();
  std::string stamp = FormatStamp(std::chrono::system_clock::to_time_t(now));
  int counter = 1;
  if (!state.last_id.empty() && stamp <= state.last_id.substr(0, 16)) {
    stamp = state.last_id.substr(0, 16);
    counter = std::stoi(state.last_id.substr(17)) + 1;
    if (counter > 9999) {
      stamp = FormatStamp(ParseStamp(stamp) + 1);
      counter = 1;
    }
  }
  char suffix[16];
  std::snprintf(suffix, sizeof(suffix), "-%04d", counter);
  return stamp + suffix;
}

std::optional<ScanInfo> InfoFromJson(const nlohmann::json& j) {
  if (!j.is_object()) return std::nullopt;
  try {
    ScanInfo info;
    info.id = j.at("id").get<std::string>();
    const auto state = ParseState(j.at("state").get<std::string>());
    if (!state || !IsValidScanId(info.id)) return std::nullopt;
    info.state = *state;
    info.reason = j.value("reason", "");
    info.frames = j.value("frames", uint64_t{0});
    info.peaks = j.value("peaks", uint64_t{0});
    info.bytes = j.value("bytes", uint64_t{0});
    info.created = j.value("created", CreatedFromId(info.id));
    info.header = j.value("header", nlohmann::json::object());
    info.footer = j.value("footer", nlohmann::json());
    return info;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

std::optional<ScanInfo> ReadMeta(const fs::path& dir, const std::string& id) {
  std::error_code ec;
  if (!fs::is_regular_file(MetaPath(dir, id), ec)) return std::nullopt;
  try {
    const auto archive_meta = MetaPath(dir, id);
    std::FILE* f = std::fopen(archive_meta.c_str(), "rb");
    if (f == nullptr) return std::nullopt;
    std::string text;
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) text.append(buf, n);
    std::fclose(f);
    auto info = InfoFromJson(nlohmann::json::parse(text));
    if (info && info->id != id) return std::nullopt;
    return info;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

void WriteMeta(const fs::path& dir, const ScanInfo& info) {
  WriteFileAtomically(MetaPath(dir, info.id), info.ToJson().dump(2) + "\n");
}

// Caller holds state.mu. Writes the metadata, or (disk full, I/O error) keeps it in memory
// so the scan's state is right at once and retries later: recovery never needs free
// space to finish. False when it was kept in memory.
bool SaveMeta(internal::StoreState& state, const ScanInfo& info) {
  try {
    WriteMeta(state.dir, info);
    state.unsaved.erase(info.id);
    return true;
  } catch (const StoreError& e) {
    state.unsaved[info.id] = info;
    state.unsaved_error = e.what();
    return false;
  }
}

// Caller holds state.mu. After space was freed: writes what was kept in memory.
void RetryUnsaved(internal::StoreState& state) {
  const auto unsaved = state.unsaved;
  for (const auto& [id, info] : unsaved) {
    if (!SaveMeta(state, info)) return;
  }
}

// Caller holds state.mu. The metadata of a scan that is not being written.
std::optional<ScanInfo> StoredInfo(const internal::StoreState& state, const std::string& id) {
  const auto it = state.unsaved.find(id);
  if (it != state.unsaved.end()) return it->second;
  return ReadMeta(state.dir, id);
}

// Metadata rebuilt from what the reader recovers. A finished archive takes its state from
// the footer; anything else is "partial" with the recovery report as the reason.
ScanInfo RecoverInfo(const fs::path& path, const std::string& id, bool renamed,
                     const std::optional<ScanInfo>& old) {
  ScanInfo info;
  info.id = id;
  info.created = old ? old->created : CreatedFromId(id);
  info.header = old ? old->header : nlohmann::json::object();
  info.state = ScanState::kPartial;
  try {
    ScanArchive archive = ReadScanFile(path);
    if (archive.header.is_object()) info.header = archive.header;
    info.frames = archive.report.frames;
    info.peaks = archive.report.peaks;
    info.bytes = archive.report.bytes_total;
    info.reason = archive.report.message;
    if (renamed && archive.report.complete && archive.footer) {
      info.footer = *archive.footer;
      const auto state = ParseState(info.footer.value("status", "complete"));
      info.state = state && IsFinished(*state) ? *state : ScanState::kComplete;
      info.reason = info.footer.value("reason", "");
    }
  } catch (const ScanFormatError& e) {
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    info.bytes = ec ? 0 : size;
    info.reason = e.what();
  }
  return info;
}

// Caller holds state.mu. Best effort: a failure is retried at the next Finish or Open.
// Crash-partial scans count (and go) like finished ones; the scan being written never.
void ApplyRetention(internal::StoreState& state) {
  if (state.options.keep_finished == 0) return;
  std::vector<std::string> finished;
  std::error_code ec;
  std::set<std::string> ids;
  for (const auto& entry : fs::directory_iterator(state.dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (!EndsWith(name, kMetaSuffix)) continue;
    ids.insert(name.substr(0, name.size() - kMetaSuffix.size()));
  }
  for (const auto& [id, info] : state.unsaved) ids.insert(id);
  for (const std::string& id : ids) {
    if (!IsValidScanId(id) || state.active.count(id) > 0) continue;
    const auto info = StoredInfo(state, id);
    if (info && (IsFinished(info->state) || info->state == ScanState::kPartial)) {
      finished.push_back(id);
    }
  }
  std::sort(finished.rbegin(), finished.rend());
  for (size_t i = state.options.keep_finished; i < finished.size(); ++i) {
    fs::remove(ArchivePath(state.dir, finished[i]), ec);
    fs::remove(PartialPath(state.dir, finished[i]), ec);
    fs::remove(MetaPath(state.dir, finished[i]), ec);
    fs::remove_all(ResultsDir(state.dir, finished[i]), ec);
    state.unsaved.erase(finished[i]);
  }
  if (finished.size() > state.options.keep_finished) {
    try {
      SyncDir(state.dir);
    } catch (const StoreError&) {
    }
  }
}

}  // namespace

bool IsValidScanId(std::string_view id) { return protocol::IsValidScanId(id); }

std::string_view ScanStateName(ScanState state) {
  switch (state) {
    case ScanState::kWriting:
      return "writing";
    case ScanState::kComplete:
      return "complete";
    case ScanState::kAborted:
      return "aborted";
    case ScanState::kFault:
      return "fault";
    case ScanState::kPartial:
      return "partial";
  }
  return "unknown";
}

nlohmann::json ScanInfo::ToJson() const {
  return {{"id", id},           {"state", std::string(ScanStateName(state))},
          {"reason", reason},   {"frames", frames},
          {"peaks", peaks},     {"bytes", bytes},
          {"created", created}, {"header", header},
          {"footer", footer}};
}

// ---------------------------------------------------------------------------------------
// ScanHandle

ScanHandle::ScanHandle(std::shared_ptr<internal::StoreState> state, ScanInfo info,
                       std::unique_ptr<ScanFileWriter> writer)
    : state_(std::move(state)), id_(info.id), info_(std::move(info)), writer_(std::move(writer)) {
  bytes_ = writer_->bytes_written();
}

ScanHandle::~ScanHandle() {
  if (closed_) return;
  writer_.reset();  // closes the file; what is on disk is what a crash would leave
  std::optional<ScanInfo> info;
  try {
    info = RecoverInfo(PartialPath(state_->dir, id_), id_, /*renamed=*/false, info_);
    info->reason = "not finished: " + info->reason;
  } catch (...) {
    // Unreadable: the next Open marks it from the archive.
  }
  Close(std::move(info));
}

void ScanHandle::Close(std::optional<ScanInfo> info) noexcept {
  std::lock_guard<std::mutex> lock(state_->mu);
  // In the same step as leaving `active`, so no reader ever sees a stale "writing".
  if (info) SaveMeta(*state_, *info);
  state_->active.erase(id_);
  closed_ = true;
}

void ScanHandle::AppendFrame(const FrameRecord& frame) {
  if (closed_) throw std::logic_error("scan " + id_ + " is already finished");
  if (failed_) {
    throw StoreError(StoreError::Kind::kIo, "scan " + id_ + ": not writable after an error");
  }
  try {
    writer_->AppendFrame(frame);
  } catch (const ScanFormatError& e) {
    failed_ = true;
    throw StoreError(StoreError::Kind::kIo, e.what());
  } catch (const std::invalid_argument& e) {
    throw StoreError(StoreError::Kind::kInvalidArgument, e.what());
  }
  frames_ += 1;
  peaks_ += frame.peaks.size();
  bytes_ = writer_->bytes_written();
}

void ScanHandle::Finish(const nlohmann::json& footer) {
  if (closed_) throw std::logic_error("scan " + id_ + " is already finished");
  if (!footer.is_object()) {
    throw StoreError(StoreError::Kind::kInvalidArgument, "scan footer must be a JSON object");
  }
  const auto status_json = footer.value("status", nlohmann::json("complete"));
  const auto state =
      status_json.is_string() ? ParseState(status_json.get<std::string>()) : std::nullopt;
  if (!state || !IsFinished(*state)) {
    throw StoreError(StoreError::Kind::kInvalidArgument,
                     "scan footer status must be \"complete\", \"aborted\" or \"fault\"");
  }
  if (failed_) {
    throw StoreError(StoreError::Kind::kIo, "scan " + id_ + ": not writable after an error");
  }
  const fs::path partial = PartialPath(state_->dir, id_);
  const fs::path archive = ArchivePath(state_->dir, id_);
  try {
    writer_->Finish(footer);  // fsyncs the file and the directory
  } catch (const ScanFormatError& e) {
    failed_ = true;
    throw StoreError(StoreError::Kind::kIo, e.what());
  }
  bytes_ = writer_->bytes_written();
  writer_.reset();
  if (::rename(partial.c_str(), archive.c_str()) != 0) {
    failed_ = true;
    ThrowIo(partial, "rename to " + archive.filename().string());
  }
  ScanInfo info = info_;
  info.state = *state;
  info.reason = footer.value("reason", nlohmann::json("")).is_string() ? footer.value("reason", "")
                                                                       : footer["reason"].dump();
  info.frames = frames_;
  info.peaks = peaks_;
  info.bytes = bytes_;
  info.footer = footer;
  // The archive is final from here on: should the metadata fail, it is kept in memory
  // (and Open rebuilds it from the archive).
  closed_ = true;
  std::lock_guard<std::mutex> lock(state_->mu);
  const bool saved = SaveMeta(*state_, info);  // fsyncs the directory: covers the rename too
  state_->active.erase(id_);
  if (!saved) {
    throw StoreError(StoreError::Kind::kIo, "scan " + id_ + ": " + state_->unsaved_error);
  }
  ApplyRetention(*state_);
}

// ---------------------------------------------------------------------------------------
// ScanStore

ScanStore::ScanStore(std::shared_ptr<internal::StoreState> state) : state_(std::move(state)) {}
ScanStore::~ScanStore() = default;

const fs::path& ScanStore::dir() const { return state_->dir; }

std::unique_ptr<ScanStore> ScanStore::Open(const fs::path& dir, ScanStoreOptions options) {
  auto state = std::make_shared<internal::StoreState>();
  state->dir = dir;
  state->options = std::move(options);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) ThrowIo(dir, "cannot create data directory", ec.value());

  std::set<std::string> ids;
  std::vector<std::string> results_dirs;
  bool removed = false;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (EndsWith(name, kTmpSuffix)) {
      fs::remove(entry.path(), ec);
      removed = true;
      continue;
    }
    if (EndsWith(name, kResultsSuffix)) {
      results_dirs.push_back(name.substr(0, name.size() - kResultsSuffix.size()));
      continue;
    }
    for (std::string_view suffix : {kPartialSuffix, kArchiveSuffix, kMetaSuffix}) {
      if (EndsWith(name, suffix)) {
        const std::string id = name.substr(0, name.size() - suffix.size());
        if (IsValidScanId(id)) ids.insert(id);
        break;
      }
    }
  }
  if (ec) ThrowIo(dir, "cannot list data directory", ec.value());

  for (const std::string& id : ids) {
    state->last_id = std::max(state->last_id, id);
    const bool has_archive = fs::is_regular_file(ArchivePath(dir, id), ec);
    const bool has_partial = fs::is_regular_file(PartialPath(dir, id), ec);
    const std::optional<ScanInfo> meta = ReadMeta(dir, id);
    if (!has_archive && !has_partial) {
      // Metadata of a scan whose deletion was cut short.
      fs::remove(MetaPath(dir, id), ec);
      removed = true;
      continue;
    }
    if (has_archive) {
      if (meta && IsFinished(meta->state)) continue;
      SaveMeta(*state, RecoverInfo(ArchivePath(dir, id), id, /*renamed=*/true, meta));
    } else {
      // Read again at every start even when the size is unchanged: a flipped bit changes
      // what is readable, not the size.
      const ScanInfo recovered = RecoverInfo(PartialPath(dir, id), id, /*renamed=*/false, meta);
      if (meta && meta->state == ScanState::kPartial && meta->ToJson() == recovered.ToJson()) {
        continue;
      }
      SaveMeta(*state, recovered);
    }
  }
  // Results: a folder whose scan is gone (a deletion cut short) goes; so do uploads that
  // never committed.
  for (const std::string& id : results_dirs) {
    const fs::path folder = ResultsDir(dir, id);
    if (!IsValidScanId(id) || ids.count(id) == 0 ||
        (!fs::exists(ArchivePath(dir, id), ec) && !fs::exists(PartialPath(dir, id), ec))) {
      fs::remove_all(folder, ec);
      removed = true;
      continue;
    }
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
      if (entry.path().filename().string().find(kUploadInfix) != std::string::npos) {
        fs::remove(entry.path(), ec);
      }
    }
  }
  if (removed) SyncDir(dir);
  {
    std::lock_guard<std::mutex> lock(state->mu);
    ApplyRetention(*state);
  }
  return std::unique_ptr<ScanStore>(new ScanStore(std::move(state)));
}

std::unique_ptr<ScanHandle> ScanStore::BeginScan(const nlohmann::json& header) {
  if (!header.is_object()) {
    throw StoreError(StoreError::Kind::kInvalidArgument, "scan header must be a JSON object");
  }
  std::lock_guard<std::mutex> lock(state_->mu);
  const std::string id = NextId(*state_);
  nlohmann::json full_header = header;
  full_header["scan_id"] = id;
  const fs::path partial = PartialPath(state_->dir, id);
  ScanFileWriterOptions writer_options;
  writer_options.fsync_every_frames = state_->options.fsync_every_frames;
  std::unique_ptr<ScanFileWriter> writer;
  try {
    writer = std::make_unique<ScanFileWriter>(partial, writer_options);
  } catch (const ScanFormatError& e) {
    throw StoreError(StoreError::Kind::kIo, e.what());
  }
  state_->last_id = id;  // taken even if the rest fails: ids are never reused
  ScanInfo info;
  info.id = id;
  info.state = ScanState::kWriting;
  info.created = CreatedFromId(id);
  info.header = full_header;
  try {
    writer->Begin(full_header);
    info.bytes = writer->bytes_written();
    WriteMeta(state_->dir, info);
  } catch (const std::exception& e) {
    // Nothing of the scan was recorded yet: remove what there is.
    writer.reset();
    std::error_code ec;
    fs::remove(partial, ec);
    fs::remove(MetaPath(state_->dir, id), ec);
    if (dynamic_cast<const StoreError*>(&e) != nullptr) throw;
    throw StoreError(StoreError::Kind::kIo, e.what());
  }
  std::unique_ptr<ScanHandle> handle(new ScanHandle(state_, std::move(info), std::move(writer)));
  state_->active[id] = handle.get();
  return handle;
}

namespace {

void CheckId(const std::string& id) {
  if (!IsValidScanId(id)) {
    throw StoreError(StoreError::Kind::kInvalidId, "not a scan id: \"" + id + "\"");
  }
}

}  // namespace

std::vector<ScanInfo> ScanStore::List() const {
  std::lock_guard<std::mutex> lock(state_->mu);
  std::set<std::string> ids;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(state_->dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (!EndsWith(name, kMetaSuffix)) continue;
    const std::string id = name.substr(0, name.size() - kMetaSuffix.size());
    if (IsValidScanId(id)) ids.insert(id);
  }
  if (ec) ThrowIo(state_->dir, "cannot list data directory", ec.value());
  for (const auto& [id, handle] : state_->active) ids.insert(id);
  for (const auto& [id, info] : state_->unsaved) ids.insert(id);
  std::vector<ScanInfo> result;
  for (auto it = ids.rbegin(); it != ids.rend(); ++it) {
    const auto active = state_->active.find(*it);
    if (active != state_->active.end()) {
      const ScanHandle& h = *active->second;
      ScanInfo info = h.info_;
      info.frames = h.frames_;
      info.peaks = h.peaks_;
      info.bytes = h.bytes_;
      result.push_back(std::move(info));
    } else if (auto info = StoredInfo(*state_, *it)) {
      result.push_back(std::move(*info));
    }
  }
  return result;
}

ScanInfo ScanStore::Get(const std::string& id) const {
  CheckId(id);
  std::lock_guard<std::mutex> lock(state_->mu);
  const auto active = state_->active.find(id);
  if (active != state_->active.end()) {
    const ScanHandle& h = *active->second;
    ScanInfo info = h.info_;
    info.frames = h.frames_;
    info.peaks = h.peaks_;
    info.bytes = h.bytes_;
    return info;
  }
  auto info = StoredInfo(*state_, id);
  if (!info) throw StoreError(StoreError::Kind::kNotFound, "no scan " + id);
  return *info;
}

fs::path ScanStore::Path(const std::string& id) const {
  CheckId(id);
  std::lock_guard<std::mutex> lock(state_->mu);
  std::error_code ec;
  const fs::path partial = PartialPath(state_->dir, id);
  const fs::path archive = ArchivePath(state_->dir, id);
  const bool active = state_->active.count(id) > 0;
  if (active && fs::exists(partial, ec)) return partial;
  if (fs::exists(archive, ec)) return archive;
  if (fs::exists(partial, ec)) return partial;
  throw StoreError(StoreError::Kind::kNotFound, "no scan " + id);
}

void ScanStore::Delete(const std::string& id) {
  CheckId(id);
  std::lock_guard<std::mutex> lock(state_->mu);
  if (state_->active.count(id) > 0) {
    throw StoreError(StoreError::Kind::kBusy, "scan " + id + " is being written");
  }
  bool found = false;
  for (const fs::path& p :
       {ArchivePath(state_->dir, id), PartialPath(state_->dir, id), MetaPath(state_->dir, id)}) {
    std::error_code ec;
    const bool removed = fs::remove(p, ec);
    if (ec) ThrowIo(p, "cannot delete", ec.value());
    found = found || removed;
  }
  found = state_->unsaved.erase(id) > 0 || found;
  if (!found) throw StoreError(StoreError::Kind::kNotFound, "no scan " + id);
  // After the archive: a deletion cut short here leaves a folder Open removes.
  std::error_code ec;
  fs::remove_all(ResultsDir(state_->dir, id), ec);
  if (ec) ThrowIo(ResultsDir(state_->dir, id), "cannot delete", ec.value());
  SyncDir(state_->dir);
  RetryUnsaved(*state_);  // the space just freed
}

namespace {

void CheckResultName(const std::string& name) {
  if (protocol::FindResultKind(name) == nullptr) {
    std::string names;
    for (const protocol::ResultKind& kind : protocol::ResultKinds()) {
      names += (names.empty() ? "" : ", ") + std::string(kind.name);
    }
    throw StoreError(StoreError::Kind::kInvalidArgument,
                     "not a result name: \"" + name + "\" (one of " + names + ")");
  }
}

// Caller holds state.mu. Whether the scan has an archive (finished or crash-partial) and
// is not being written; kNotFound or kBusy otherwise.
void CheckFinishedScan(const internal::StoreState& state, const std::string& id) {
  if (state.active.count(id) > 0) {
    throw StoreError(StoreError::Kind::kBusy, "scan " + id + " is being written");
  }
  std::error_code ec;
  if (!fs::exists(ArchivePath(state.dir, id), ec) && !fs::exists(PartialPath(state.dir, id), ec)) {
    throw StoreError(StoreError::Kind::kNotFound, "no scan " + id);
  }
}

}  // namespace

ResultUpload::ResultUpload(std::shared_ptr<internal::StoreState> state, std::string id,
                           std::string name, fs::path temp, int fd)
    : state_(std::move(state)),
      id_(std::move(id)),
      name_(std::move(name)),
      temp_(std::move(temp)),
      fd_(fd) {}

ResultUpload::~ResultUpload() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(temp_.c_str());
}

void ResultUpload::Append(const char* data, size_t size) {
  if (fd_ < 0) throw StoreError(StoreError::Kind::kIo, temp_.string() + ": upload already ended");
  while (size > 0) {
    const ssize_t n = ::write(fd_, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd_);
      fd_ = -1;
      ThrowIo(temp_, "write", err);
    }
    data += n;
    size -= static_cast<size_t>(n);
    bytes_ += static_cast<uint64_t>(n);
  }
}

void ResultUpload::Commit() {
  if (fd_ < 0) throw StoreError(StoreError::Kind::kIo, temp_.string() + ": upload already ended");
  const int fd = fd_;
  fd_ = -1;
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    ThrowIo(temp_, "fsync", err);
  }
  if (::close(fd) != 0) ThrowIo(temp_, "close");
  // Under the lock, so a Delete either ran before (the folder is gone: kNotFound) or
  // runs after and takes the new file with it.
  std::lock_guard<std::mutex> lock(state_->mu);
  CheckFinishedScan(*state_, id_);
  const fs::path target = ResultsDir(state_->dir, id_) / name_;
  if (::rename(temp_.c_str(), target.c_str()) != 0) {
    if (errno == ENOENT) throw StoreError(StoreError::Kind::kNotFound, "no scan " + id_);
    ThrowIo(target, "rename");
  }
  committed_ = true;
  SyncDir(target.parent_path());
}

std::unique_ptr<ResultUpload> ScanStore::BeginResult(const std::string& id,
                                                     const std::string& name) {
  CheckId(id);
  CheckResultName(name);
  std::lock_guard<std::mutex> lock(state_->mu);
  CheckFinishedScan(*state_, id);
  const fs::path folder = ResultsDir(state_->dir, id);
  if (::mkdir(folder.c_str(), 0755) == 0) {
    SyncDir(state_->dir);
  } else if (errno != EEXIST) {
    ThrowIo(folder, "cannot create");
  }
  const fs::path temp =
      folder / (name + std::string(kUploadInfix) + std::to_string(++state_->next_upload));
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) ThrowIo(temp, "cannot create");
  return std::unique_ptr<ResultUpload>(new ResultUpload(state_, id, name, temp, fd));
}

std::vector<StoredResult> ScanStore::Results(const std::string& id) const {
  CheckId(id);
  std::lock_guard<std::mutex> lock(state_->mu);
  std::error_code ec;
  if (state_->active.count(id) == 0 && !fs::exists(ArchivePath(state_->dir, id), ec) &&
      !fs::exists(PartialPath(state_->dir, id), ec)) {
    throw StoreError(StoreError::Kind::kNotFound, "no scan " + id);
  }
  std::vector<StoredResult> results;
  const fs::path folder = ResultsDir(state_->dir, id);
  for (const protocol::ResultKind& kind : protocol::ResultKinds()) {
    const fs::path file = folder / std::string(kind.name);
    const auto status = fs::status(file, ec);
    if (ec || !fs::is_regular_file(status)) continue;
    StoredResult result;
    result.name = std::string(kind.name);
    result.bytes = fs::file_size(file, ec);
    result.modified = fs::last_write_time(file, ec);
    if (!ec) results.push_back(std::move(result));
  }
  return results;
}

fs::path ScanStore::ResultPath(const std::string& id, const std::string& name) const {
  CheckId(id);
  CheckResultName(name);
  const fs::path file = ResultsDir(state_->dir, id) / name;
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) {
    throw StoreError(StoreError::Kind::kNotFound, "scan " + id + " has no result " + name);
  }
  return file;
}

std::string ScanStore::problem() const {
  std::lock_guard<std::mutex> lock(state_->mu);
  if (state_->unsaved.empty()) return "";
  return "the metadata of " + std::to_string(state_->unsaved.size()) +
         " scan(s) could not be written (" + state_->unsaved_error + ")";
}

}  // namespace mirrorscan::store
