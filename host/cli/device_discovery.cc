#include "host/cli/device_discovery.h"

#include <chrono>
#include <memory>
#include <stdexcept>

#include <avahi-client/client.h>
#include <avahi-client/lookup.h>
#include <avahi-common/error.h>
#include <avahi-common/malloc.h>
#include <avahi-common/simple-watch.h>

#include "common/protocol/protocol.h"

namespace mirrorscan::cli {
namespace {

struct Browse {
  AvahiClient* client = nullptr;
  std::vector<DiscoveredDevice> found;
};

void OnResolved(AvahiServiceResolver* resolver, AvahiIfIndex, AvahiProtocol,
                AvahiResolverEvent event, const char* name, const char*, const char*,
                const char* host, const AvahiAddress* address, uint16_t port, AvahiStringList* txt,
                AvahiLookupResultFlags, void* userdata) {
  auto* browse = static_cast<Browse*>(userdata);
  if (event == AVAHI_RESOLVER_FOUND && address != nullptr) {
    DiscoveredDevice device;
    device.name = name;
    device.host = host;
    char text[AVAHI_ADDRESS_STR_MAX];
    avahi_address_snprint(text, sizeof(text), address);
    device.address = text;
    device.port = port;
    for (AvahiStringList* item = txt; item != nullptr; item = avahi_string_list_get_next(item)) {
      device.txt.emplace_back(reinterpret_cast<const char*>(avahi_string_list_get_text(item)),
                              avahi_string_list_get_size(item));
    }
    browse->found.push_back(std::move(device));
  }
  avahi_service_resolver_free(resolver);
}

void OnBrowse(AvahiServiceBrowser*, AvahiIfIndex interface, AvahiProtocol protocol,
              AvahiBrowserEvent event, const char* name, const char* type, const char* domain,
              AvahiLookupResultFlags, void* userdata) {
  auto* browse = static_cast<Browse*>(userdata);
  if (event != AVAHI_BROWSER_NEW) return;
  avahi_service_resolver_new(browse->client, interface, protocol, name, type, domain,
                             AVAHI_PROTO_UNSPEC, static_cast<AvahiLookupFlags>(0), OnResolved,
                             browse);
}

}  // namespace

std::vector<DiscoveredDevice> DiscoverDevices(double seconds) {
  std::unique_ptr<AvahiSimplePoll, void (*)(AvahiSimplePoll*)> poll(avahi_simple_poll_new(),
                                                                    avahi_simple_poll_free);
  if (!poll) throw std::runtime_error("discover: cannot create an Avahi event loop");
  Browse browse;
  int error = 0;
  std::unique_ptr<AvahiClient, void (*)(AvahiClient*)> client(
      avahi_client_new(avahi_simple_poll_get(poll.get()), static_cast<AvahiClientFlags>(0), nullptr,
                       nullptr, &error),
      avahi_client_free);
  if (!client) {
    throw std::runtime_error(std::string("discover: Avahi is not available (") +
                             avahi_strerror(error) +
                             "); start avahi-daemon, or give the device with --host H:P "
                             "(the virtual board is at the address its board.json listens on)");
  }
  browse.client = client.get();
  const std::string type(protocol::kServiceType);
  AvahiServiceBrowser* browser =
      avahi_service_browser_new(client.get(), AVAHI_IF_UNSPEC, AVAHI_PROTO_UNSPEC, type.c_str(),
                                nullptr, static_cast<AvahiLookupFlags>(0), OnBrowse, &browse);
  if (browser == nullptr) {
    throw std::runtime_error(std::string("discover: cannot browse for ") + type + ": " +
                             avahi_strerror(avahi_client_errno(client.get())));
  }
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int>(seconds * 1000));
  while (std::chrono::steady_clock::now() < deadline) {
    if (avahi_simple_poll_iterate(poll.get(), 100) != 0) break;
  }
  avahi_service_browser_free(browser);
  return browse.found;
}

}  // namespace mirrorscan::cli
