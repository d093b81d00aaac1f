#pragma once

// `mirrorscan device discover`: browse DNS-SD (Avahi) for _mirrorscan._tcp.

#include <string>
#include <vector>

namespace mirrorscan::cli {

struct DiscoveredDevice {
  std::string name;     // the service instance name
  std::string host;     // its mDNS host name
  std::string address;  // IPv4 or IPv6
  int port = 0;
  std::vector<std::string> txt;  // "key=value" records (board, api version)
};

// Listens for `seconds`. Throws std::runtime_error with a hint when the Avahi daemon is not
// reachable (as in containers and the virtual board's test machines).
std::vector<DiscoveredDevice> DiscoverDevices(double seconds);

}  // namespace mirrorscan::cli
