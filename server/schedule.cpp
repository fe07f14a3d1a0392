#include "server/schedule.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cassert>
#include <limits>
#include <string>
#include <utility>

#include "proto/lod.hpp"
#include "server/metrics.hpp"

namespace grotto::server {

namespace {

double seconds_between(ScheduleTime a, ScheduleTime b) {
  return std::chrono::duration<double>(b - a).count();
}

Delivery error_delivery(RoomKey key, Error error) {
  Delivery d;
  d.key = key;
  d.error = std::move(error);
  return d;
}

Error stopping_error() {
  return Error{ErrorCode::kServiceRestart, "the generation service is stopping"};
}

}  // namespace

Schedule::Schedule(ScheduleConfig config, Metrics& metrics)
    : config_(config), metrics_(metrics), cache_(config.cache_bytes) {
  worlds_.emplace(config_.own_seed, World{});
  metrics_.worlds_open.set(1);
}

// ---- clients and worlds ----

Status Schedule::joinable(uint64_t seed) const {
  if (stopping_ && seed != config_.own_seed) {
    // Opening a world (and closing another) for a client that gets nothing built is no use.
    return stopping_error();
  }
  if (config_.max_worlds == 1 && seed != config_.own_seed) {
    return Error{ErrorCode::kWorldMismatch, "this server serves seed " +
                                                std::to_string(config_.own_seed) + ", not " +
                                                std::to_string(seed)};
  }
  return {};
}

Result<ClientId> Schedule::join(uint64_t seed, uint32_t version, Build build) {
  if (Status s = joinable(seed); !s) return s.error();
  auto world = worlds_.find(seed);
  if (world == worlds_.end()) {
    if (worlds_.size() >= config_.max_worlds) {
      auto idle = worlds_.end();
      for (auto it = worlds_.begin(); it != worlds_.end(); ++it) {
        if (it->first == config_.own_seed || it->second.clients > 0) continue;
        if (idle == worlds_.end() || it->second.last_used < idle->second.last_used) idle = it;
      }
      if (idle == worlds_.end()) {
        metrics_.worlds_refused.add();
        return Error{ErrorCode::kOverloaded,
                     "this server has its " + std::to_string(config_.max_worlds) +
                         " worlds (max_worlds) open and players in each; world " +
                         std::to_string(seed) + " cannot open now, retry later"};
      }
      spdlog::info("event=world_closed seed={} reason=idle", idle->first);
      emit(sched::CloseWorld{idle->first});
      worlds_.erase(idle);
    }
    world = worlds_.emplace(seed, World{}).first;
    metrics_.worlds_opened.add();
    metrics_.worlds_open.set(static_cast<int64_t>(worlds_.size()));
    spdlog::info("event=world_opened seed={} worlds_open={}", seed, worlds_.size());
    emit(sched::OpenWorld{seed});
  }
  Client client;
  client.id = next_client_++;
  client.seed = seed;
  client.version = version;
  client.build = build;
  ++world->second.clients;
  world->second.last_used = ++world_clock_;
  const ClientId id = client.id;
  clients_.emplace(id, std::move(client));
  return id;
}

void Schedule::leave(ClientId id) {
  auto it = clients_.find(id);
  if (it == clients_.end()) return;
  Client& client = it->second;
  while (!client.wants.empty())
    drop_want(client, client.wants.begin());
  World& world = worlds_.at(client.seed);
  --world.clients;
  world.last_used = ++world_clock_;
  clients_.erase(it);
  queued_clients_.erase(id);
  publish_gauges();
}

// ---- wants ----

void Schedule::request(ClientId id, std::span<const Want> wants, ScheduleTime now) {
  auto c = clients_.find(id);
  if (c == clients_.end()) return;
  Client& client = c->second;
  bool queued = false;
  for (const Want& w : wants) {
    if (!proto::mesh_lod(w.lod)) {
      emit(sched::Deliver{
          id, error_delivery(
                  {w.id, static_cast<uint8_t>(std::min(w.lod, 255u)), client.seed, client.version},
                  invalid_argument("lod " + std::to_string(w.lod) + " is not served"))});
      continue;
    }
    RoomKey key{w.id, static_cast<uint8_t>(w.lod), client.seed, client.version};
    if (stopping_) {
      emit(sched::Deliver{id, error_delivery(key, stopping_error())});
      continue;
    }
    if (auto known = client.wants.find(key); known != client.wants.end()) {
      // Already waiting: only the priority changes (its place among equals stays).
      Waiting& want = known->second;
      if (want.queued) {
        client.queue.erase({want.priority, want.seq, key});
        client.queue.insert({w.priority, want.seq, key});
      }
      want.priority = w.priority;
      want.due = now + std::chrono::milliseconds(w.priority);
      continue;
    }
    if (RoomPtr hit = cache_.find(key)) {
      metrics_.rooms_from_cache.add();
      metrics_.room_latency_seconds.observe(0);
      Delivery d;
      d.key = key;
      d.room = std::move(hit);
      d.from_cache = true;
      emit(sched::Deliver{id, std::move(d)});
      continue;
    }
    Waiting want{w.priority, next_seq_++, now, false, now + std::chrono::milliseconds(w.priority)};
    auto j = jobs_.find(key);
    if (j != jobs_.end()) {
      metrics_.rooms_deduplicated.add();
      Job& job = j->second;
      if (job.stage == Job::Stage::kFetching && client.build == Build::kHere) {
        // This replica is the room's owner: the tier sent our own fetch back here. Waiting for
        // the fetch would wait for ourselves; the job is built here now.
        build_here(key, job, now);
        queued = true;
      }
      job.waiters.push_back(id);
      want.queued = job.stage == Job::Stage::kQueued;
    } else {
      Job& job = jobs_.emplace(key, Job{next_job_++, Job::Stage::kQueued, {id}, now}).first->second;
      // A room due now (a stream's first room, a player at its portal) is built here: the player
      // already waits, and waiting for an owner busy with everyone's first rooms too made the
      // start of a crowd stall (bench/cluster.sh: 0-35 stalls, 134-585 owner failures; built
      // here, 0 stalls and 23-32).
      if (config_.owners && client.build == Build::kAnywhere && w.priority > 0) {
        fetch(key, job, w.priority);
      } else {
        by_age_.push_back({job.id, key});
        ++queued_jobs_;
        want.queued = true;
        queued = true;
      }
    }
    if (want.queued) {
      client.queue.insert({want.priority, want.seq, key});
      touch(client);
    }
    client.wants.emplace(key, want);
    metrics_.rooms_in_flight.add(1);
  }
  publish_gauges();
  if (queued) emit(sched::Wake{});
}

void Schedule::cancel(ClientId id, std::span<const cave::RoomId> rooms) {
  auto c = clients_.find(id);
  if (c == clients_.end()) return;
  Client& client = c->second;
  for (cave::RoomId room : rooms) {
    // Every lod of the room: keys order by id first (and a client's wants are of one world).
    auto it = client.wants.lower_bound(RoomKey{room, 0, 0, 0});
    while (it != client.wants.end() && it->first.id == room) {
      auto next = std::next(it);
      drop_want(client, it);
      it = next;
    }
  }
  publish_gauges();
}

// ---- the ledger ----

// After a change to c's queue: whether c has queued wants.
void Schedule::touch(const Client& c) {
  if (c.queue.empty()) {
    queued_clients_.erase(c.id);
  } else {
    queued_clients_.insert(c.id);
  }
}

void Schedule::publish_gauges() {
  metrics_.queue_depth.set(static_cast<int64_t>(queued_jobs_));
  metrics_.cache_bytes.set(static_cast<int64_t>(cache_.bytes()));
  metrics_.cache_entries.set(static_cast<int64_t>(cache_.entries()));
}

Schedule::Job* Schedule::find(const JobRef& ref) {
  auto it = jobs_.find(ref.key);
  return it != jobs_.end() && it->second.id == ref.job ? &it->second : nullptr;
}

// Answers one want of `client`: forgets it and delivers.
void Schedule::answer(Client& client, const RoomKey& key, Delivery d, ScheduleTime now) {
  auto it = client.wants.find(key);
  assert(it != client.wants.end());
  if (it->second.queued) {
    client.queue.erase({it->second.priority, it->second.seq, key});
    touch(client);
  }
  metrics_.room_latency_seconds.observe(seconds_between(it->second.received, now));
  client.wants.erase(it);
  metrics_.rooms_in_flight.add(-1);
  emit(sched::Deliver{client.id, std::move(d)});
}

// Ends a job for every waiter with the same outcome and forgets it.
void Schedule::finish_job(Jobs::iterator job, const RoomPtr& room,
                          const std::optional<Error>& error, ScheduleTime now) {
  if (job->second.stage == Job::Stage::kQueued) --queued_jobs_;
  for (ClientId id : job->second.waiters) {
    auto c = clients_.find(id);
    assert(c != clients_.end());
    Delivery d;
    d.key = job->first;
    d.room = room;
    d.error = error;
    answer(c->second, job->first, std::move(d), now);
  }
  jobs_.erase(job);
}

// Removes one want of a client (cancel or leave); a queued job nobody waits for goes.
void Schedule::drop_want(Client& client, std::map<RoomKey, Waiting, RoomKeyLess>::iterator it) {
  RoomKey key = it->first;
  if (it->second.queued) {
    client.queue.erase({it->second.priority, it->second.seq, key});
    touch(client);
  }
  client.wants.erase(it);
  metrics_.rooms_in_flight.add(-1);
  metrics_.rooms_cancelled.add();
  auto j = jobs_.find(key);
  if (j == jobs_.end()) return;
  std::erase(j->second.waiters, client.id);
  if (j->second.waiters.empty() && j->second.stage == Job::Stage::kQueued) {
    --queued_jobs_;
    jobs_.erase(j);
  }
}

// ---- workers ----

void Schedule::expire(ScheduleTime now) {
  while (!by_age_.empty()) {
    const JobRef ref = by_age_.front();
    Job* job = find(ref);
    if (job && job->stage == Job::Stage::kQueued) {
      if (now - job->created < config_.job_deadline) break;
      metrics_.rooms_failed.add();
      finish_job(
          jobs_.find(ref.key), nullptr,
          Error{ErrorCode::kOverloaded, "room " + ref.key.id.to_string() + " waited longer than " +
                                            std::to_string(config_.job_deadline.count()) +
                                            " ms for a builder; retry later"},
          now);
    }
    by_age_.pop_front();
  }
  publish_gauges();
}

// How many queued jobs a free worker takes: all it may (max_batch_rooms) while the queue keeps
// every worker busy, else an even share with the workers waiting for work, so that a few wants
// (one player's first rooms) are built and encoded on every core instead of one worker's while
// the others wait. A batch's rooms are built on its worker's thread alone
// (RoomBuilder::Options::threads is 1 in the server), so one batch is one core.
Batch Schedule::start_batch(ScheduleTime now, size_t idle_workers) {
  Batch batch;
  const size_t share = (queued_jobs_ + idle_workers) / (idle_workers + 1);
  batch.limit = std::clamp<size_t>(share, 1, config_.max_batch_rooms);
  take_jobs(batch, now);
  return batch;
}

void Schedule::top_up(Batch& batch, ScheduleTime now) {
  take_jobs(batch, now);
}

void Schedule::seal(Batch& batch) {
  std::erase_if(batch.jobs, [&](const JobRef& ref) {
    auto it = jobs_.find(ref.key);
    assert(it != jobs_.end() && it->second.id == ref.job);
    if (!it->second.waiters.empty()) return false;
    jobs_.erase(it);
    return true;
  });
  publish_gauges();
}

void Schedule::built(const JobRef& ref, Result<RoomPtr> room, ScheduleTime now) {
  auto it = jobs_.find(ref.key);
  assert(it != jobs_.end() && it->second.id == ref.job);
  if (room) {
    cache_.insert(*room);
    finish_job(it, *room, std::nullopt, now);
  } else {
    metrics_.rooms_failed.add();
    finish_job(it, nullptr, room.error(), now);
  }
  publish_gauges();
}

// Moves queued jobs into the batch by deadline class (ScheduleConfig::urgent_within): first the
// wants already due (the player is in the room or at its portal: a stream's first room,
// priority 0), then the urgent ones (take_due), then any, round-robin from the client served
// last (take_any). A client's turn takes its smallest priority. All jobs of a batch share the lod
// of its first job; worlds may mix (one launch serves them all). A batch holding urgent jobs is
// not topped up with prefetch: its rooms are built, encoded and delivered before far ones, each
// as soon as it is encoded, while the other workers take the prefetch.
void Schedule::take_jobs(Batch& batch, ScheduleTime now) {
  if (config_.urgent_within.count() > 0) {
    const size_t before = batch.jobs.size();
    take_due(batch, now, now + config_.urgent_within);
    if (batch.jobs.size() > before) batch.urgent = true;
  }
  if (!batch.urgent) take_any(batch);
}

// A client's most urgent queued want that fits the batch (of its lod, once it has a job).
std::set<Schedule::QueueEntry>::iterator Schedule::head(Client& c, const Batch& batch) {
  auto e = c.queue.begin();
  if (!batch.jobs.empty()) {
    const uint8_t lod = batch.jobs.front().key.lod;
    while (e != c.queue.end() && e->key.lod != lod)
      ++e;
  }
  return e;
}

// Moves the job of `e` (in c's queue) into the batch.
void Schedule::take_job(Client& c, std::set<QueueEntry>::iterator e, Batch& batch) {
  const RoomKey key = e->key;
  Job& job = jobs_.at(key);
  assert(job.stage == Job::Stage::kQueued);
  job.stage = Job::Stage::kBuilding;
  --queued_jobs_;
  // The job leaves every waiter's queue; the wants stay until it is answered.
  for (ClientId id : job.waiters) {
    Client& w = clients_.at(id);
    Waiting& want = w.wants.at(key);
    w.queue.erase({want.priority, want.seq, key});
    want.queued = false;
    touch(w);
  }
  batch.jobs.push_back({job.id, key});
  rr_cursor_ = c.id;
}

// Prefetch: round-robin across the clients with queued wants, one job each in turn, from the
// client after the one served last.
void Schedule::take_any(Batch& batch) {
  std::vector<ClientId> order;
  while (batch.jobs.size() < batch.limit && queued_jobs_ > 0) {
    order.assign(queued_clients_.upper_bound(rr_cursor_), queued_clients_.end());
    order.insert(order.end(), queued_clients_.begin(), queued_clients_.upper_bound(rr_cursor_));
    bool progress = false;
    for (ClientId id : order) {
      if (batch.jobs.size() >= batch.limit) break;
      Client& c = clients_.at(id);
      auto e = head(c, batch);  // taking a job takes it from every waiter's queue
      if (e == c.queue.end()) continue;
      take_job(c, e, batch);
      progress = true;
    }
    if (!progress) break;
  }
}

// The deadline classes: first the wants due by `now`, then those due by `window`, each earliest
// deadline first with one job per client a round. Each round orders the clients whose most
// urgent want is due by then by that want's due time and takes one job from each in that order:
// the player who reaches a missing room soonest goes first (a stream's first room before another
// player's next one), and a client calling everything urgent still gets one job a round. The
// clients with queued wants are scanned once a call (thousands of them, under the generator's
// lock); the rounds look again only at those found due by `window`.
void Schedule::take_due(Batch& batch, ScheduleTime now, ScheduleTime window) {
  if (queued_jobs_ == 0 || batch.jobs.size() >= batch.limit) return;
  std::vector<std::pair<ScheduleTime, Client*>> due;
  for (ClientId id : queued_clients_) {
    Client& c = clients_.at(id);
    auto e = head(c, batch);
    if (e == c.queue.end()) continue;
    const auto at = c.wants.at(e->key).due;
    if (at <= window) due.emplace_back(at, &c);
  }
  auto earlier = [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second->id < b.second->id;
  };
  for (const ScheduleTime until : {now, window}) {
    while (batch.jobs.size() < batch.limit && !due.empty()) {
      std::sort(due.begin(), due.end(), earlier);
      bool progress = false;
      size_t kept = 0;
      for (auto& [at, client] : due) {
        // The batch's lod is set by its first job, and taking a job takes it from every
        // waiter: each client's head is looked at again.
        auto e = head(*client, batch);
        if (e == client->queue.end() || client->wants.at(e->key).due > window) continue;
        if (client->wants.at(e->key).due <= until && batch.jobs.size() < batch.limit) {
          take_job(*client, e, batch);
          progress = true;
          e = head(*client, batch);
          if (e == client->queue.end() || client->wants.at(e->key).due > window) continue;
        }
        due[kept++] = {client->wants.at(e->key).due, client};
      }
      due.resize(kept);
      if (!progress) break;
    }
  }
}

// ---- owners ----

// Asks the room's owner for a new job's room. The wait is the want's slack (its priority, the
// time until the player can reach the room, less what building it here may take behind other
// work), between kMinOwnerWait and owner_timeout: a room the player is about to enter is built
// here if its owner has not answered within kMinOwnerWait (a silent owner costs that, not
// owner_timeout), far prefetch waits the whole timeout.
void Schedule::fetch(const RoomKey& key, Job& job, uint32_t priority_ms) {
  constexpr std::chrono::milliseconds kBuildHere{500}, kMinOwnerWait{150};
  const auto slack = std::chrono::milliseconds{priority_ms} - kBuildHere;
  const auto wait =
      std::clamp(slack, std::min(kMinOwnerWait, config_.owner_timeout), config_.owner_timeout);
  job.stage = Job::Stage::kFetching;
  emit(sched::Fetch{{job.id, key}, priority_ms, wait});
}

bool Schedule::fetch_wanted(const JobRef& ref) const {
  auto it = jobs_.find(ref.key);
  return it != jobs_.end() && it->second.id == ref.job && it->second.stage == Job::Stage::kFetching;
}

void Schedule::fetched(const JobRef& ref, Result<RoomPtr> room, bool wanted, ScheduleTime now) {
  auto it = jobs_.find(ref.key);
  const bool fetching =
      it != jobs_.end() && it->second.id == ref.job && it->second.stage == Job::Stage::kFetching;
  if (!fetching) {
    // Built here meanwhile (build_here, e.g. the owner was this replica): the room, when it was
    // checked all the same, is kept.
    if (wanted && room) cache_.insert(*room);
  } else if (room) {
    metrics_.rooms_fetched.add();
    cache_.insert(*room);
    finish_job(it, *room, std::nullopt, now);
  } else {
    metrics_.owner_failures.add();
    spdlog::warn("event=owner_fetch_failed seed={} room={} lod={} error=\"{}\"", ref.key.seed,
                 ref.key.id.to_string(), ref.key.lod, room.error().message);
    if (it->second.waiters.empty()) {
      jobs_.erase(it);
    } else if (stopping_) {
      finish_job(it, nullptr, stopping_error(), now);
    } else {
      build_here(ref.key, it->second, now);
      emit(sched::Wake{});
    }
  }
  publish_gauges();
}

// A fetching job goes to this replica's builders: into every waiter's queue, where it was
// (priority, then arrival). Its fetch's answer, when it comes, is not waited for.
void Schedule::build_here(const RoomKey& key, Job& job, ScheduleTime now) {
  job.stage = Job::Stage::kQueued;
  job.created = now;
  ++queued_jobs_;
  by_age_.push_back({job.id, key});
  for (ClientId id : job.waiters) {
    Client& w = clients_.at(id);
    Waiting& want = w.wants.at(key);
    want.queued = true;
    w.queue.insert({want.priority, want.seq, key});
    touch(w);
  }
}

// ---- shutdown ----

void Schedule::shutdown(ScheduleTime now) {
  if (stopping_) return;
  stopping_ = true;
  size_t failed = 0;
  for (auto it = jobs_.begin(); it != jobs_.end();) {
    auto next = std::next(it);
    if (it->second.stage == Job::Stage::kQueued) {
      metrics_.rooms_failed.add();
      finish_job(it, nullptr, stopping_error(), now);
      ++failed;
    }
    it = next;
  }
  by_age_.clear();
  emit(sched::Wake{});
  spdlog::info("event=generator_stopping failed_queued={}", failed);
  publish_gauges();
}

std::vector<sched::Action> Schedule::take() {
  return std::exchange(actions_, {});
}

std::chrono::milliseconds Schedule::oldest_urgent(ScheduleTime now) const {
  return oldest_queued(now, true);
}

std::chrono::milliseconds Schedule::oldest_want(ScheduleTime now) const {
  return oldest_queued(now, false);
}

std::chrono::milliseconds Schedule::oldest_queued(ScheduleTime now, bool urgent_only) const {
  if (clients_.empty()) return std::chrono::milliseconds{0};
  const auto urgent = urgent_only ? static_cast<uint64_t>(config_.urgent_within.count())
                                  : std::numeric_limits<uint64_t>::max();
  // Each client's oldest (urgent) want still queued; clients with none waiting count as 0.
  std::vector<ScheduleTime::duration> ages(clients_.size(), ScheduleTime::duration{0});
  size_t n = 0;
  for (ClientId id : queued_clients_) {
    const Client& c = clients_.at(id);
    std::optional<ScheduleTime> oldest;
    for (const QueueEntry& e : c.queue) {
      if (e.priority > urgent) break;  // the queue is by priority: the rest is prefetch
      const ScheduleTime received = c.wants.at(e.key).received;
      if (!oldest || received < *oldest) oldest = received;
    }
    if (oldest && *oldest < now) ages[n++] = now - *oldest;
  }
  // The 90th percentile over the clients, not the maximum: one client asking a thousand rooms
  // due now waits for its own backlog (round-robin serves everyone else first), which says
  // nothing about whether the others are served in time.
  const size_t k = (ages.size() - 1) * 9 / 10;
  std::nth_element(ages.begin(), ages.begin() + static_cast<std::ptrdiff_t>(k), ages.end());
  return std::chrono::duration_cast<std::chrono::milliseconds>(ages[k]);
}

}  // namespace grotto::server
