#include "host/pipeline/upload.h"

#include "common/protocol/protocol.h"
#include "host/client/device_client.h"
#include "host/pipeline/pipeline.h"

namespace mirrorscan::pipeline {
namespace {

void CheckScanId(const std::string& scan_id) {
  if (!protocol::IsValidScanId(scan_id)) {
    throw UploadError("upload: the archive names no device scan id (\"" + scan_id +
                      "\"); was it fetched from a device?");
  }
}

}  // namespace

void CheckUploadTarget(const std::string& device, const std::string& token,
                       const std::string& scan_id) {
  CheckScanId(scan_id);
  try {
    client::DeviceClient(device, token).Get(scan_id);
  } catch (const client::DeviceError& e) {
    throw UploadError(std::string("upload: ") + e.what() + "; nothing processed");
  }
}

std::vector<std::string> UploadResults(const std::string& device, const std::string& token,
                                       const std::filesystem::path& out,
                                       const nlohmann::json& summary) {
  const std::string scan_id = summary.value("scan_id", "");
  CheckScanId(scan_id);
  std::vector<std::string> names;
  if (summary.value("ok", false)) {
    for (const protocol::ResultKind& kind : protocol::ResultKinds()) {
      const std::string name(kind.name);
      if (name != "summary.json" && std::filesystem::is_regular_file(out / name)) {
        names.push_back(name);
      }
    }
  }
  names.push_back("summary.json");
  try {
    client::DeviceClient client(device, token);
    for (const std::string& name : names) client.PutResult(scan_id, name, out / name);
  } catch (const client::DeviceError& e) {
    throw UploadError(std::string("upload: ") + e.what());
  }
  return names;
}

}  // namespace mirrorscan::pipeline
