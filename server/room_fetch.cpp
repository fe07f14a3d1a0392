#include "server/room_fetch.hpp"

#include <atomic>
#include <memory>
#include <utility>

namespace grotto::server {

void fetch_room(Generator& generator, const RoomKey& key, uint32_t priority, Build build,
                PostFn post, RoomDoneFn done) {
  // A generator client of its own for this one want: its delivery (a cache hit inside request(),
  // or a worker's) is handed to `post`, where the client is removed. remove_client cannot run in
  // the delivery callback itself: it waits for the client's callbacks to finish.
  auto client = std::make_shared<std::atomic<ClientId>>(0);
  auto deliver = [&generator, client, post, done](Delivery d) {
    post([&generator, client, d = std::move(d), done]() mutable {
      generator.remove_client(client->load());
      if (d.error) return done(std::move(*d.error));
      done(std::move(d.room));
    });
  };
  auto id = generator.add_client(key.seed, std::move(deliver), key.version, build);
  if (!id) {
    return post([done, e = id.error()]() mutable { done(std::move(e)); });
  }
  client->store(*id);
  const Want want{key.id, key.lod, priority};
  generator.request(*id, std::span(&want, 1));
}

}  // namespace grotto::server
