// The browser viewer (web/): grotto-server serves it at / from its own binary, every
// file embedded at build time (web/tools/bundle.mjs writes the table), so a server needs nothing
// beside it and the page works offline, with nothing from a CDN.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace grotto::server {

struct ViewerAsset {
  std::string_view path;          // what it is served at: /index.html, /viewer/..., /viewer/lib/...
  std::string_view content_type;  // text/html, text/javascript or application/wasm
  std::string_view etag;          // strong, quoted: 64-bit FNV-1a of the bytes
  std::span<const unsigned char> bytes;
};

// Every file of the viewer, in the bundle's order.
std::span<const ViewerAsset> viewer_assets();

// The asset served at a request's path (no query): "/" is /index.html; nullptr for none.
const ViewerAsset* find_viewer_asset(std::string_view path);

}  // namespace grotto::server
