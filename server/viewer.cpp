#include "server/viewer.hpp"

namespace grotto::server {

const ViewerAsset* find_viewer_asset(std::string_view path) {
  if (path == "/") path = "/index.html";
  for (const ViewerAsset& a : viewer_assets())
    if (a.path == path) return &a;
  return nullptr;
}

}  // namespace grotto::server
