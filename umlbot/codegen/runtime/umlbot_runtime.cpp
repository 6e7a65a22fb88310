// umlbot runtime for generated orchestrators: see umlbot_runtime.hpp. Mirrors the Python
// orchestrator (umlbot/services/orchestrator): the same topics, envelopes, time-outs, trace
// events, retained status, heartbeat, fail-safe stops and exit codes (docs/codegen.md).
#include "umlbot_runtime.hpp"

#include <malloc.h>
#include <mosquitto.h>
#include <mqtt_protocol.h>  // MQTT 5 reason codes and subscription options (libmosquitto-dev)
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <random>
#include <set>

namespace umlbot {

namespace {

using Clock = std::chrono::steady_clock;

constexpr double kConnectTimeoutS = 5.0;
constexpr double kFinalStopTimeoutS = 1.0;
constexpr double kReconnectWaitS = 10.0;
constexpr double kActuatorsBackS = 2.0;
constexpr double kBrokerGoneWindowS = 5.0;
constexpr double kTraceWindowS = 0.020;
constexpr size_t kTraceBatch = 500;
constexpr size_t kTraceMaxPending = 20000;
constexpr size_t kMaxReasonChars = 200;
const char* const kBrokerLost = "connection to the MQTT broker lost";

std::string fmt_g(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string dump(const Value& v) { return v.dump(-1, ' ', false, Value::error_handler_t::replace); }

// --- logging (stderr, one line an event) ---------------------------------------------------------

int g_log_level = 20;  // DEBUG 10, INFO 20, WARNING 30, ERROR 40

void log_line(int level, const std::string& event, const std::string& detail = "") {
  if (level < g_log_level) return;
  const char* name = level >= 40 ? "error" : level >= 30 ? "warning" : level >= 20 ? "info" : "debug";
  // stdio, not iostreams: the program links no stream or locale machinery (memory, start-up)
  std::string out = std::string("[") + name + "] " + event;
  if (!detail.empty()) out += " " + detail;
  out += "\n";
  std::fwrite(out.data(), 1, out.size(), stderr);
  std::fflush(stderr);
}

// --- broker settings ------------------------------------------------------------------------------

struct Settings {
  std::string url_shown;
  bool tls = false;
  std::string host;
  int port = 1883;
  std::string user, password;
  std::string ca, cert, key;
  bool insecure = false;
  int keepalive = 30;
  // "auto" (MQTT 5, 3.1.1 where the broker refuses 5), "5" or "3.1.1": `?protocol=`, as in Python
  std::string protocol = "auto";
};

int hexval(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percent_decode(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() + 0 && hexval(s[i + 1]) >= 0 && hexval(s[i + 2]) >= 0) {
      out += static_cast<char>(hexval(s[i + 1]) * 16 + hexval(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// mqtt://user:***@host:port: a password never reaches a log line or an error message.
std::string redact(const std::string& url) {
  auto scheme_end = url.find("://");
  if (scheme_end == std::string::npos) return url;
  auto at = url.rfind('@');
  if (at == std::string::npos || at < scheme_end) return url;
  auto colon = url.find(':', scheme_end + 3);
  if (colon == std::string::npos || colon > at) return url;
  return url.substr(0, colon + 1) + "***" + url.substr(at);
}

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
struct StartError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string lower(std::string text) {
  for (auto& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// Python's BrokerSettings._protocol: the same spellings, the same error
std::string parse_protocol(const std::string& value, const std::string& bad) {
  std::string text = lower(value);
  const auto blank = text.find_first_not_of(" \t\r\n");
  text = blank == std::string::npos ? "" : text.substr(blank, text.find_last_not_of(" \t\r\n") - blank + 1);
  if (text == "auto" || text.empty()) return "auto";
  if (text == "3" || text == "3.1.1" || text == "311" || text == "4" || text == "v311") return "3.1.1";
  if (text == "5" || text == "5.0" || text == "v5") return "5";
  throw StartError(bad + "protocol must be auto, 3.1.1 or 5");
}

Settings parse_url(const std::string& raw) {
  Settings s;
  std::string url = raw;
  while (!url.empty() && std::isspace(static_cast<unsigned char>(url.back()))) url.pop_back();
  while (!url.empty() && std::isspace(static_cast<unsigned char>(url.front()))) url.erase(0, 1);
  s.url_shown = redact(url);
  const std::string bad = "bad broker URL " + s.url_shown + ": ";
  auto scheme_end = url.find("://");
  std::string scheme = scheme_end == std::string::npos ? "" : url.substr(0, scheme_end);
  std::transform(scheme.begin(), scheme.end(), scheme.begin(), ::tolower);
  if (scheme != "mqtt" && scheme != "mqtts")
    throw StartError(bad + "the scheme must be mqtt:// or mqtts:// (e.g. mqtt://127.0.0.1:1883)");
  s.tls = scheme == "mqtts";
  s.port = s.tls ? 8883 : 1883;
  std::string rest = url.substr(scheme_end + 3);
  std::string query;
  auto q = rest.find('?');
  if (q != std::string::npos) {
    query = rest.substr(q + 1);
    rest = rest.substr(0, q);
  }
  auto slash = rest.find('/');
  if (slash != std::string::npos) {
    std::string path = rest.substr(slash);
    if (path != "/") throw StartError(bad + "unexpected path '" + path + "'");
    rest = rest.substr(0, slash);
  }
  auto at = rest.rfind('@');
  if (at != std::string::npos) {
    std::string login = rest.substr(0, at);
    rest = rest.substr(at + 1);
    auto colon = login.find(':');
    s.user = percent_decode(login.substr(0, colon));
    if (colon != std::string::npos) s.password = percent_decode(login.substr(colon + 1));
  }
  auto colon = rest.rfind(':');
  if (colon != std::string::npos && rest.find(']') == std::string::npos) {
    std::string port = rest.substr(colon + 1);
    rest = rest.substr(0, colon);
    char* end = nullptr;
    long value = port.empty() ? -1 : std::strtol(port.c_str(), &end, 10);
    if (port.empty() || *end != '\0' || value < 0 || value > 65535)
      throw StartError(bad + "Port could not be cast to integer value as '" + port + "'");
    s.port = static_cast<int>(value);
  }
  s.host = rest;
  if (s.host.empty()) throw StartError(bad + "no host (e.g. mqtt://127.0.0.1:1883)");
  for (size_t from = 0; from <= query.size();) {
    size_t amp = query.find('&', from);
    if (amp == std::string::npos) amp = query.size();
    const std::string item = query.substr(from, amp - from);
    from = amp + 1;
    if (item.empty()) continue;
    auto eq = item.find('=');
    std::string k = percent_decode(item.substr(0, eq));
    std::string v = eq == std::string::npos ? "" : percent_decode(item.substr(eq + 1));
    if (k == "ca") s.ca = v;
    else if (k == "cert") s.cert = v;
    else if (k == "key") s.key = v;
    else if (k == "insecure") s.insecure = v == "1" || v == "true" || v == "yes";
    else if (k == "keepalive") s.keepalive = std::max(5, std::atoi(v.c_str()));
    else if (k == "protocol") s.protocol = parse_protocol(v, bad);
    else throw StartError(bad + "unknown parameter(s) " + k + " (known: ca, cert, insecure, keepalive, key, protocol)");
  }
  return s;
}

// --- the run's state ------------------------------------------------------------------------------

struct Slot {
  bool done = false;
  bool lost = false;
  Value reply;
};

struct Board {  // one signal name: accept nodes waiting, and the held occurrence
  int waiting = 0;
  uint64_t gen = 0;
  Value last;
  bool held = false;
  Value held_value;
};

enum class Phase { Starting, Running, Stopping, Stopped, Failed };
const char* phase_name(Phase p) {
  switch (p) {
    case Phase::Starting: return "starting";
    case Phase::Running: return "running";
    case Phase::Stopping: return "stopping";
    case Phase::Stopped: return "stopped";
    case Phase::Failed: return "failed";
  }
  return "?";
}

struct Options {
  std::string broker;
  std::string ca_file;
  std::string robot;
  std::string trace_file;
  bool trace = true;
  double call_timeout_s = -1;
  double grace_s = 2.0;
  double startup_timeout_s = 10.0;
  double speed = 1.0;
  bool sim_clock = false;  // sleeps on the simulator's clock (hidden option --sim-clock)
};

struct State {
  const ModelInfo* model = nullptr;
  Options opts;
  Settings settings;
  std::string base;  // umlbot/<robot>
  std::string reply_topic;
  std::string id_prefix;
  uint64_t next_id = 0;
  double call_timeout_s = 2.0;
  mosquitto* mosq = nullptr;
  std::atomic<bool> connected{false};
  bool ever_connected = false;
  std::string connect_error;
  // MQTT 5 unless asked for 3.1.1 or the broker refused 5 ("auto"): set before the network thread runs
  bool mqtt5 = true;
  bool fall_back = false;  // "auto" and the broker refused MQTT 5: connect again with 3.1.1
  // libmosquitto's network thread ended instead of reconnecting: the heartbeat thread starts it again
  bool loop_dead = false;
  std::map<std::string, std::shared_ptr<Slot>> pending;
  std::map<std::string, std::string> availability;
  std::set<std::string> components;
  std::set<std::string> accepted;
  std::map<std::string, Board> boards;
  uint64_t ignored_signals = 0;
  Clock::time_point foreign_logged_at{};
  bool foreign_logged = false;
  // life
  Phase phase = Phase::Starting;
  std::string phase_reason;
  bool has_reason = false;
  std::string fault;
  bool failed = false;
  bool fault_is_symptom = false;
  Clock::time_point symptom_at{};
  std::string exit_reason;
  bool exit_requested_flag = false;
  std::atomic<bool> exit_requested{false};
  bool has_deadline = false;
  Clock::time_point exit_deadline{};
  int lanes_running = 0;
  bool connecting = false;
  // trace
  std::deque<std::string> trace_pending;
  uint64_t trace_recorded = 0;
  uint64_t trace_dropped = 0;
  bool trace_closing = false;
  bool trace_on = false;
  std::FILE* trace_out = nullptr;
  // heartbeat
  bool heartbeat_stop = false;
  bool closing = false;  // the final status is out: a disconnect now is ours
  // the simulator's clock (--sim-clock): see sim_report_locked
  int sim_busy = 0;              // lane and token threads not in an idle wait (a call counts as busy)
  uint64_t sim_woken = 0;        // wake messages handled
  uint64_t sim_next = 0;         // sleep ids
  std::set<uint64_t> sim_sleeping;  // ids of the sleeps waiting for their wake
  std::set<uint64_t> sim_fired;     // ids woken, not yet seen by their thread
  int sim_busy_sent = -1;
  uint64_t sim_woken_sent = 0;
};

State g;

double elapsed(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}
Clock::time_point after(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// Every publish goes through one lock: libmosquitto's threaded mode was seen to interleave two
// threads' packets on a loaded machine (the broker then closed the connection: "out of memory").
int publish_raw(const char* topic, int length, const void* payload, int qos, bool retain, int* mid = nullptr) {
  static std::mutex publishing;
  std::lock_guard<std::mutex> lock(publishing);
  return mosquitto_publish(g.mosq, mid, topic, length, payload, qos, retain);
}

// the final status's message id, and whether the broker acknowledged it
std::atomic<int> g_final_mid{-1};
std::atomic<bool> g_final_acked{false};

void on_publish(mosquitto*, void*, int mid) {
  if (mid != g_final_mid.load()) return;
  g_final_acked = true;
  Runtime& rt = runtime();
  std::lock_guard<std::mutex> lock(rt.mu);
  rt.cv.notify_all();
}

bool active() { return g.phase == Phase::Running || g.phase == Phase::Stopping; }

void publish(const std::string& topic, const std::string& payload, int qos, bool retain) {
  int rc = publish_raw(topic.c_str(), static_cast<int>(payload.size()),
                             payload.data(), qos, retain);
  if (rc != MOSQ_ERR_SUCCESS) throw ModelError("NotConnected", std::string("cannot publish on ") + topic + ": " + mosquitto_strerror(rc));
}

// --- the simulator's clock (--sim-clock) -------------------------------------------------------------
// With --sim-clock the program's sleeps take sim time: the simulator (umlbot/sim/program.py) owns
// the clock, which moves to the next deadline only while the program has nothing to do. The
// program says on <base>/sim/clock/program, in order: {"sleep":id,"s":seconds} when a lane starts
// a sleep, {"cancel":id} when one ends early, {"busy":n,"woken":w} whenever n (the lane and token
// threads not waiting for a sleep, a signal or their forked tokens; a call in flight is busy)
// or w (the wakes handled) changed. The simulator answers {"wake":id,"now":t} on
// <base>/sim/clock/sim when a sleep's deadline is reached. A thread that wakes another counts it
// busy at once (the wake handler, the last token of a fork, a signal), so n never drops to 0
// between a wake and the thread it wakes running. Off by default: a robot sleeps in wall time.

// A clock message (never throws: a lost connection shows as a stall of the simulator's time).
void sim_publish(const std::string& payload) {
  const std::string topic = g.base + "/sim/clock/program";
  publish_raw(topic.c_str(), static_cast<int>(payload.size()), payload.data(), 0, false);
}

void sim_report_locked() {
  if (!g.opts.sim_clock) return;
  if (g.sim_busy == g.sim_busy_sent && g.sim_woken == g.sim_woken_sent) return;
  g.sim_busy_sent = g.sim_busy;
  g.sim_woken_sent = g.sim_woken;
  const std::string payload = "{\"busy\":" + std::to_string(g.sim_busy) + ",\"woken\":" + std::to_string(g.sim_woken) + "}";
  sim_publish(payload);
}

// A thread starts (or is handed) work: it counts as busy; -1: it ends or waits.
void sim_busy_locked(int delta) {
  if (!g.opts.sim_clock) return;
  g.sim_busy += delta;
  sim_report_locked();
}

void on_sim_wake(const std::string& payload) {
  Value v = Value::parse(payload, nullptr, false);
  if (v.is_discarded() || !v.is_object() || !v.contains("wake") || !v["wake"].is_number_unsigned()) return;
  const uint64_t id = v["wake"].get<uint64_t>();
  ++g.sim_woken;
  if (g.sim_sleeping.erase(id)) {
    g.sim_fired.insert(id);
    ++g.sim_busy;  // handed to the sleeping thread
  }
  sim_report_locked();
  runtime().cv.notify_all();
}

// Called with g's lock held.
void publish_status_locked() {
  if (!g.connected) return;
  Value status = Value::object();
  status["state"] = phase_name(g.phase);
  status["reason"] = g.has_reason ? Value(g.phase_reason) : Value();
  status["model"] = g.model->name;
  status["robot"] = g.opts.robot;
  status["source_hash"] = g.model->source_hash;
  status["call_timeout_s"] = g.call_timeout_s;
  status["since"] = now();
  try {
    const std::string topic = g.base + "/orchestrator/status";
    const std::string payload = dump(status);
    int mid = -1;
    int rc = publish_raw(topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1, true, &mid);
    if (rc != MOSQ_ERR_SUCCESS) throw ModelError("NotConnected", mosquitto_strerror(rc));
    if (g.phase == Phase::Stopped || g.phase == Phase::Failed) g_final_mid = mid;
  } catch (const std::exception& e) {
    log_line(30, "orchestrator status not published", e.what());
  }
}

void enter_locked(Phase phase, const std::string* reason) {
  g.phase = phase;
  g.has_reason = reason != nullptr;
  g.phase_reason = reason ? *reason : "";
  publish_status_locked();
}

// The first fault: remember it, request the end, wake the supervisor. Lock held.
void fail_locked(const std::string& reason, bool broker_symptom) {
  if (g.failed) return;
  g.failed = true;
  g.fault = reason;
  if (broker_symptom) {
    g.fault_is_symptom = true;
    g.symptom_at = Clock::now();
  }
  g.exit_requested = true;
  log_line(30, "fail_safe_stop", "reason=" + reason);
  Runtime& rt = runtime();
  rt.cv.notify_all();
}

std::string shorten(const std::string& reason) {
  if (reason.size() <= kMaxReasonChars) return reason;
  // cut on a UTF-8 character boundary
  size_t cut = kMaxReasonChars;
  while (cut > 0 && (static_cast<unsigned char>(reason[cut]) & 0xC0) == 0x80) --cut;
  return reason.substr(0, cut) + "\xE2\x80\xA6 (" + std::to_string(reason.size()) + " characters)";
}

void request_exit_locked(const std::string& reason) {
  Runtime& rt = runtime();
  if (!g.exit_requested_flag) {
    g.exit_requested_flag = true;
    g.exit_reason = reason;
    g.exit_requested = true;
    g.has_deadline = true;
    g.exit_deadline = after(g.opts.grace_s);
    log_line(20, "exit_requested", "reason=" + reason);
    if (g.phase == Phase::Running) enter_locked(Phase::Stopping, &reason);
  } else {
    g.exit_deadline = Clock::now();  // asked twice: no more grace
  }
  rt.cv.notify_all();
}

// --- MQTT callbacks (libmosquitto's network thread: short work under the lock only) --------------

// Over MQTT 5 every subscription asks for Retain As Published, as the Python side's do: a retained
// exit request or signal published while the program runs (or passed on by a fleet bridge on every
// reconnect) then still looks retained here and is ignored as stale (docs/fleet.md). Over 3.1.1 the
// broker clears RETAIN on what it forwards to a subscriber.
void subscribe(const std::string& topic, int qos) {
  if (g.mqtt5)
    mosquitto_subscribe_v5(g.mosq, nullptr, topic.c_str(), qos, MQTT_SUB_OPT_RETAIN_AS_PUBLISHED, nullptr);
  else
    mosquitto_subscribe(g.mosq, nullptr, topic.c_str(), qos);
}

void subscribe_all() {
  const std::string topics[] = {g.base + "/+/status", g.base + "/signal/+", g.base + "/orchestrator/exit",
                                g.reply_topic};
  for (const auto& t : topics) subscribe(t, t == g.reply_topic ? 0 : 1);
  if (g.opts.sim_clock) subscribe(g.base + "/sim/clock/sim", 0);
}

void on_connect(mosquitto*, void*, int rc) {
  Runtime& rt = runtime();
  std::lock_guard<std::mutex> lock(rt.mu);
  if (rc == MQTT_RC_UNSUPPORTED_PROTOCOL_VERSION && g.mqtt5 && g.settings.protocol == "auto") {
    g.fall_back = true;  // a 3.1.1-only broker (amqtt): start-up connects again with 3.1.1
    rt.cv.notify_all();
    return;
  }
  if (rc != 0) {
    // MQTT 5 reason codes (128 and up) have their own texts ("Bad user name or password")
    g.connect_error = std::string("the broker refused the connection: ") +
                      (rc >= 128 ? mosquitto_reason_string(rc) : mosquitto_connack_string(rc));
    rt.cv.notify_all();
    return;
  }
  g.connected = true;
  g.ever_connected = true;
  subscribe_all();
  publish_status_locked();  // a broker without persistence forgets retained messages
  rt.cv.notify_all();
}

// True when libmosquitto's network thread ends after this disconnect instead of reconnecting: the
// broker's own DISCONNECT (MQTT 5 only: reason codes 128 and up, e.g. "Server shutting down" on a
// broker restart) and the errors mosquitto_loop_forever gives up on (an MQTT 5 CONNACK refusal).
bool network_thread_ends(int rc) {
  switch (rc) {
    case MOSQ_ERR_NOMEM: case MOSQ_ERR_PROTOCOL: case MOSQ_ERR_INVAL: case MOSQ_ERR_NOT_FOUND:
    case MOSQ_ERR_TLS: case MOSQ_ERR_PAYLOAD_SIZE: case MOSQ_ERR_NOT_SUPPORTED: case MOSQ_ERR_AUTH:
    case MOSQ_ERR_ACL_DENIED: case MOSQ_ERR_UNKNOWN: case MOSQ_ERR_EAI: case MOSQ_ERR_PROXY:
      return true;
    default:
      return rc >= 128;
  }
}

void on_disconnect(mosquitto*, void*, int rc) {
  Runtime& rt = runtime();
  std::lock_guard<std::mutex> lock(rt.mu);
  log_line(10, "mqtt_disconnected", "rc=" + std::to_string(rc));
  if (!g.closing && network_thread_ends(rc)) g.loop_dead = true;
  if (!g.connected) return;
  if (rc == 0 || g.closing) {  // our own goodbye at the end: not a fault
    g.connected = false;
    rt.cv.notify_all();
    return;
  }
  g.connected = false;
  g.availability.clear();  // stale: the retained status comes again after the reconnect
  for (auto& entry : g.pending) {
    entry.second->done = true;
    entry.second->lost = true;
  }
  if (g.fault_is_symptom && elapsed(g.symptom_at) < kBrokerGoneWindowS) {
    // the broker went down and sent the last wills first: name the fault after its end
    g.fault = kBrokerLost;
    g.fault_is_symptom = false;
  }
  if (active()) fail_locked(kBrokerLost, true);
  else if (g.phase == Phase::Starting) log_line(30, "connection to the broker lost during start-up; waiting for it");
  rt.cv.notify_all();
}

Value parse_or_text(const std::string& payload) {
  if (payload.empty()) return Value();
  Value v = Value::parse(payload, nullptr, false);
  if (v.is_discarded()) return Value(payload);
  return v;
}

void on_status(const std::string& component, const std::string& payload) {
  if (!g.components.count(component)) return;
  std::string state = "offline";
  if (!payload.empty()) {
    Value v = Value::parse(payload, nullptr, false);
    if (v.is_discarded() || !v.is_object() || !v.contains("state") || !v["state"].is_string()) {
      log_line(30, "bad component status", "component=" + component);
      return;
    }
    state = v["state"].get<std::string>();
  }
  std::string previous = g.availability.count(component) ? g.availability[component] : "";
  g.availability[component] = state;
  if (previous != state) log_line(20, "component_status", "component=" + component + " state=" + state);
  bool required = std::find(g.model->required.begin(), g.model->required.end(), component) != g.model->required.end();
  if (state != "online" && previous == "online" && required && active())
    fail_locked("component " + component + " went " + state, true);
  runtime().cv.notify_all();
}

void on_signal(const std::string& name, const std::string& payload) {
  if (!g.accepted.count(name)) {
    ++g.ignored_signals;
    if (!g.foreign_logged || elapsed(g.foreign_logged_at) >= 60.0) {
      g.foreign_logged = true;
      g.foreign_logged_at = Clock::now();
      log_line(30, "ignoring signals that no accept node of the model waits for", "signal=" + name);
    }
    return;
  }
  Board& board = g.boards[name];
  Value value = parse_or_text(payload);
  if (board.waiting > 0) {
    board.last = std::move(value);
    ++board.gen;
    sim_busy_locked(board.waiting);  // handed to the accept nodes it wakes
    runtime().cv.notify_all();
  } else {
    board.held = true;
    board.held_value = std::move(value);
  }
}

void on_exit_message(const std::string& payload, bool retained) {
  if (retained) {
    log_line(30, "ignoring a retained exit request");
    return;
  }
  if (payload.empty()) return;
  Value v = Value::parse(payload, nullptr, false);
  if (v.is_discarded()) {
    log_line(30, "ignoring an exit request that is not JSON");
    return;
  }
  if (!v.is_object()) {
    log_line(30, "ignoring an exit request that is not a JSON object");
    return;
  }
  std::string reason = "exit requested over MQTT";
  if (v.contains("reason") && !v["reason"].is_null()) {
    if (!v["reason"].is_string()) {
      log_line(30, "ignoring an exit request whose reason is not a string");
      return;
    }
    std::string text = v["reason"].get<std::string>();
    if (!text.empty()) reason += ": " + shorten(text);
  }
  request_exit_locked(reason);
}

void on_message(mosquitto*, void*, const mosquitto_message* message) {
  const std::string topic = message->topic;
  const std::string payload(static_cast<const char*>(message->payload),
                            static_cast<size_t>(message->payloadlen));
  Runtime& rt = runtime();
  std::lock_guard<std::mutex> lock(rt.mu);
  if (topic == g.reply_topic) {
    Value reply = Value::parse(payload, nullptr, false);
    if (reply.is_discarded() || !reply.is_object() || !reply.contains("id") || !reply["id"].is_string()) return;
    auto found = g.pending.find(reply["id"].get<std::string>());
    if (found == g.pending.end()) return;
    found->second->reply = std::move(reply);
    found->second->done = true;
    rt.cv.notify_all();
    return;
  }
  if (topic.compare(0, g.base.size() + 1, g.base + "/") != 0) return;
  const std::string rest = topic.substr(g.base.size() + 1);
  if (rest == "sim/clock/sim") {
    if (g.opts.sim_clock) on_sim_wake(payload);
  } else if (rest == "orchestrator/exit") {
    on_exit_message(payload, message->retain);
  } else if (rest.compare(0, 7, "signal/") == 0) {
    if (!message->retain) on_signal(rest.substr(7), payload);
  } else {
    auto slash = rest.find('/');
    if (slash != std::string::npos && rest.substr(slash) == "/status") on_status(rest.substr(0, slash), payload);
  }
}

// --- trace -----------------------------------------------------------------------------------------

void ship_locked(std::unique_lock<std::mutex>& lock) {
  size_t count = std::min(kTraceBatch, g.trace_pending.size());
  if (!count) return;
  std::vector<std::string> texts(std::make_move_iterator(g.trace_pending.begin()),
                                 std::make_move_iterator(g.trace_pending.begin() + static_cast<long>(count)));
  g.trace_pending.erase(g.trace_pending.begin(), g.trace_pending.begin() + static_cast<long>(count));
  lock.unlock();
  if (g.opts.trace && g.connected) {
    std::string array = "[";
    for (size_t i = 0; i < texts.size(); ++i) {
      if (i) array += ",";
      array += texts[i];
    }
    array += "]";
    publish_raw((g.base + "/orchestrator/trace").c_str(), static_cast<int>(array.size()),
                      array.data(), 0, false);
  }
  if (g.trace_out != nullptr) {
    for (const auto& t : texts) {
      std::fwrite(t.data(), 1, t.size(), g.trace_out);
      std::fputc('\n', g.trace_out);
    }
    std::fflush(g.trace_out);
  }
  lock.lock();
}

void trace_thread() {
  Runtime& rt = runtime();
  std::unique_lock<std::mutex> lock(rt.mu);
  Clock::time_point last_ship = Clock::now() - std::chrono::seconds(1);
  while (true) {
    rt.cv.wait(lock, [] { return !g.trace_pending.empty() || g.trace_closing; });
    if (g.trace_closing) break;
    auto ready = last_ship + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(kTraceWindowS));
    if (Clock::now() < ready && g.trace_pending.size() < kTraceBatch) {
      rt.cv.wait_until(lock, ready, [] { return g.trace_closing || g.trace_pending.size() >= kTraceBatch; });
      if (g.trace_closing) break;
    }
    last_ship = Clock::now();
    ship_locked(lock);
  }
  while (!g.trace_pending.empty()) ship_locked(lock);
}

}  // namespace

// --- operators -------------------------------------------------------------------------------------

namespace {
const char* tname(const Value& v) {
  if (v.is_boolean()) return "bool";
  if (v.is_number_integer()) return "int";
  if (v.is_number_float()) return "float";
  if (v.is_string()) return "str";
  if (v.is_null()) return "NoneType";
  if (v.is_array()) return "list";
  return "dict";
}
bool is_num(const Value& v) { return v.is_number() || v.is_boolean(); }
bool is_int(const Value& v) { return v.is_number_integer() || v.is_boolean(); }
int64_t as_int(const Value& v) { return v.is_boolean() ? (v.get<bool>() ? 1 : 0) : v.get<int64_t>(); }
double as_dbl(const Value& v) { return v.is_boolean() ? (v.get<bool>() ? 1.0 : 0.0) : v.get<double>(); }
[[noreturn]] void unsupported(const char* op, const Value& a, const Value& b) {
  throw ModelError("TypeError", std::string("unsupported operand type(s) for ") + op + ": '" + tname(a) + "' and '" + tname(b) + "'");
}
[[noreturn]] void not_ordered(const char* op, const Value& a, const Value& b) {
  throw ModelError("TypeError", std::string("'") + op + "' not supported between instances of '" + tname(a) + "' and '" + tname(b) + "'");
}
int compare(const char* op, const Value& a, const Value& b) {
  if (is_int(a) && is_int(b)) return as_int(a) < as_int(b) ? -1 : as_int(a) > as_int(b) ? 1 : 0;
  if (is_num(a) && is_num(b)) return as_dbl(a) < as_dbl(b) ? -1 : as_dbl(a) > as_dbl(b) ? 1 : 0;
  if (a.is_string() && b.is_string()) {
    int c = a.get_ref<const std::string&>().compare(b.get_ref<const std::string&>());
    return c < 0 ? -1 : c > 0 ? 1 : 0;
  }
  not_ordered(op, a, b);
}
}  // namespace

bool truthy(const Value& v) {
  if (v.is_null()) return false;
  if (v.is_boolean()) return v.get<bool>();
  if (v.is_number_integer()) return v.get<int64_t>() != 0;
  if (v.is_number_float()) return v.get<double>() != 0.0;
  if (v.is_string()) return !v.get_ref<const std::string&>().empty();
  return !v.empty();
}

Value op_add(const Value& a, const Value& b) {
  if (is_int(a) && is_int(b)) return Value(as_int(a) + as_int(b));
  if (is_num(a) && is_num(b)) return Value(as_dbl(a) + as_dbl(b));
  if (a.is_string() && b.is_string()) return Value(a.get<std::string>() + b.get<std::string>());
  if (a.is_array() && b.is_array()) {
    Value out = a;
    for (const auto& item : b) out.push_back(item);
    return out;
  }
  unsupported("+", a, b);
}
Value op_sub(const Value& a, const Value& b) {
  if (is_int(a) && is_int(b)) return Value(as_int(a) - as_int(b));
  if (is_num(a) && is_num(b)) return Value(as_dbl(a) - as_dbl(b));
  unsupported("-", a, b);
}
Value op_mul(const Value& a, const Value& b) {
  if (is_int(a) && is_int(b)) return Value(as_int(a) * as_int(b));
  if (is_num(a) && is_num(b)) return Value(as_dbl(a) * as_dbl(b));
  if (a.is_string() && is_int(b)) {
    std::string out;
    for (int64_t i = 0; i < as_int(b); ++i) out += a.get_ref<const std::string&>();
    return Value(out);
  }
  if (is_int(a) && b.is_string()) return op_mul(b, a);
  unsupported("*", a, b);
}
Value op_div(const Value& a, const Value& b) {
  if (!(is_num(a) && is_num(b))) unsupported("/", a, b);
  if (as_dbl(b) == 0.0) throw ModelError("ZeroDivisionError", is_int(a) && is_int(b) ? "division by zero" : "float division by zero");
  if (is_int(a) && is_int(b)) return Value(static_cast<double>(as_int(a)) / static_cast<double>(as_int(b)));
  return Value(as_dbl(a) / as_dbl(b));
}
Value op_mod(const Value& a, const Value& b) {
  if (is_int(a) && is_int(b)) {
    int64_t x = as_int(a), y = as_int(b);
    if (y == 0) throw ModelError("ZeroDivisionError", "integer modulo by zero");
    int64_t r = x % y;
    if (r != 0 && ((r < 0) != (y < 0))) r += y;
    return Value(r);
  }
  if (is_num(a) && is_num(b)) {
    double x = as_dbl(a), y = as_dbl(b);
    if (y == 0.0) throw ModelError("ZeroDivisionError", "float modulo");
    double r = std::fmod(x, y);
    if (r != 0.0 && ((r < 0) != (y < 0))) r += y;
    else if (r == 0.0) r = std::copysign(0.0, y);
    return Value(r);
  }
  unsupported("%", a, b);
}
Value op_eq(const Value& a, const Value& b) {
  if (is_num(a) && is_num(b)) {
    if (is_int(a) && is_int(b)) return Value(as_int(a) == as_int(b));
    return Value(as_dbl(a) == as_dbl(b));
  }
  if (is_num(a) != is_num(b)) return Value(false);
  return Value(a == b);
}
Value op_ne(const Value& a, const Value& b) { return Value(!op_eq(a, b).get<bool>()); }
Value op_lt(const Value& a, const Value& b) { return Value(compare("<", a, b) < 0); }
Value op_le(const Value& a, const Value& b) { return Value(compare("<=", a, b) <= 0); }
Value op_gt(const Value& a, const Value& b) { return Value(compare(">", a, b) > 0); }
Value op_ge(const Value& a, const Value& b) { return Value(compare(">=", a, b) >= 0); }
Value op_not(const Value& a) { return Value(!truthy(a)); }
Value op_neg(const Value& a) {
  if (is_int(a)) return Value(-as_int(a));
  if (a.is_number_float()) return Value(-a.get<double>());
  throw ModelError("TypeError", std::string("bad operand type for unary -: '") + tname(a) + "'");
}

// --- datastores ----------------------------------------------------------------------------------

Value Datastore::get() const {
  std::lock_guard<std::mutex> lock(mu_);
  return value_;
}
void Datastore::set(Value value) {
  std::lock_guard<std::mutex> lock(mu_);
  value_ = std::move(value);
}

// --- activations ---------------------------------------------------------------------------------

double now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

Activation::Activation(const char* lane, Walker walker, const NodeInfo* nodes, Activation* parent)
    : lane_(lane), walker_(walker), nodes_(nodes), parent_(parent) {}

Activation::~Activation() { cancel_tokens(); }

bool Activation::cancelled() const {
  if (runtime().cancelled) return true;
  for (const Activation* a = this; a != nullptr; a = a->parent_)
    if (a->cancelled_) return true;
  return false;
}

void Activation::checkpoint() const {
  if (cancelled()) throw Cancelled{};
}

void Activation::run(int start) {
  Outcome outcome;
  try {
    outcome = walker_(*this, start, -1);
  } catch (...) {
    cancel_tokens();
    throw;
  }
  if (outcome == Outcome::Forked) {
    Runtime& rt = runtime();
    std::unique_lock<std::mutex> lock(rt.mu);
    if (!(finished_ || failure_ || cancelled())) {  // (a wait that ends at once is no idle time)
      waiting_ = true;
      sim_busy_locked(-1);
      rt.cv.wait(lock, [&] { return finished_ || failure_ || cancelled(); });
      if (waiting_) sim_busy_locked(1);  // not handed over by the last token: woken by a cancellation
      waiting_ = false;
    }
    std::exception_ptr failure = failure_;
    bool cut = !finished_ && !failure_;
    lock.unlock();
    cancel_tokens();
    if (failure) std::rethrow_exception(failure);
    if (cut) throw Cancelled{};
  } else {
    cancel_tokens();
  }
}

void Activation::cancel_tokens() {
  Runtime& rt = runtime();
  while (true) {
    std::vector<std::thread> threads;
    {
      std::lock_guard<std::mutex> lock(rt.mu);
      cancelled_ = true;
      rt.cv.notify_all();
      threads.swap(threads_);
    }
    if (threads.empty()) return;
    for (auto& t : threads) t.join();
  }
}

Outcome Activation::fork(int node, std::initializer_list<int> targets) {
  passed(node);
  Runtime& rt = runtime();
  std::lock_guard<std::mutex> lock(rt.mu);
  if (cancelled_) throw Cancelled{};
  for (int target : targets) {
    ++live_;
    sim_busy_locked(1);  // the token's thread counts from now
    threads_.emplace_back(&Activation::token, this, target, node);
  }
  return Outcome::Forked;
}

void Activation::token(int target, int from) {
  Outcome outcome = Outcome::Stopped;
  std::exception_ptr error;
  try {
    outcome = walker_(*this, target, from);
  } catch (const Cancelled&) {
  } catch (...) {
    error = std::current_exception();
  }
  Runtime& rt = runtime();
  std::lock_guard<std::mutex> lock(rt.mu);
  --live_;
  if (error && !failure_) failure_ = error;
  if (outcome == Outcome::Ended || live_ == 0) finished_ = true;
  int handed = 0;
  if (waiting_ && (finished_ || failure_)) {  // the activation's walk goes on: hand it this thread's turn
    waiting_ = false;
    handed = 1;
  }
  sim_busy_locked(handed - 1);
  rt.cv.notify_all();
}

bool Activation::arrive(int join, int prev, std::initializer_list<int> incoming) {
  checkpoint();
  std::lock_guard<std::mutex> lock(runtime().mu);
  ++arrivals_[{join, prev}];
  for (int source : incoming)
    if (arrivals_[{join, source}] <= 0) return false;  // this flow waits here; the last one continues
  for (int source : incoming) --arrivals_[{join, source}];
  return true;
}

void Activation::passed(int node) {
  checkpoint();
  const double t = now();
  runtime().trace(lane_, nodes_[node], t, now(), nullptr, nullptr, nullptr);
}

Value Activation::step(int node, Value (*body)(Activation&)) {
  checkpoint();
  const double began = now();
  Value value;
  try {
    value = body(*this);
  } catch (...) {
    fail_current(node, began);
  }
  traced(node, began, value.is_null() ? nullptr : &value, nullptr);
  return value;
}

int Activation::decide(int node, int (*choose)(Activation&)) {
  checkpoint();
  const double began = now();
  int target = -1;
  try {
    target = choose(*this);
  } catch (...) {
    fail_current(node, began);
  }
  if (target < 0) {
    static const std::string warning = "no guard holds and there is no else: this flow stops";
    traced(node, began, nullptr, &warning);
    return -1;
  }
  const Value value(nodes_[target].id);
  traced(node, began, &value, nullptr);
  return target;
}

void Activation::traced(int node, double began, const Value* value, const std::string* warning) {
  runtime().trace(lane_, nodes_[node], began, now(), value, nullptr, warning);
}

void Activation::fail_current(int node, double began) {
  try {
    throw;
  } catch (const Cancelled&) {
    throw;
  } catch (const NodeFailed&) {
    throw;
  } catch (const ModelError& e) {
    failed(node, began, e.type.c_str(), e.what());
  } catch (const nlohmann::json::exception& e) {
    failed(node, began, "TypeError", e.what());
  } catch (const std::exception& e) {
    failed(node, began, "RuntimeError", e.what());
  }
}

void Activation::failed(int node, double began, const char* type, const std::string& message) {
  const NodeInfo& info = nodes_[node];
  const std::string error = message.empty() ? std::string(type) : std::string(type) + ": " + message;
  runtime().trace(lane_, info, began, now(), nullptr, &error, nullptr);
  std::string what = std::string("lane ") + lane_ + ", node " + info.id;
  if (info.label[0]) what += std::string(" (") + info.label + ")";
  throw NodeFailed(what + ": " + message);
}

// --- the runtime API -----------------------------------------------------------------------------

Runtime& runtime() {
  static Runtime rt;
  return rt;
}

Value Runtime::call(Activation& act, const char* component, const char* feature, Value args) {
  const std::string where = std::string(component) + "." + feature;
  auto slot = std::make_shared<Slot>();
  std::string id;
  {
    std::lock_guard<std::mutex> lock(mu);
    if (!g.connected)
      throw ModelError("NotConnected", "cannot call " + where + ": not connected to the MQTT broker at " + g.settings.url_shown);
    id = g.id_prefix + std::to_string(++g.next_id);
    g.pending[id] = slot;
  }
  Value request = Value::object();
  request["id"] = id;
  request["reply_to"] = g.reply_topic;
  request["args"] = std::move(args);
  request["timeout_s"] = g.call_timeout_s;
  const std::string topic = g.base + "/" + component + "/call/" + feature;
  const std::string payload = dump(request);
  int rc = publish_raw(topic.c_str(), static_cast<int>(payload.size()), payload.data(), 0, false);
  std::unique_lock<std::mutex> lock(mu);
  if (rc != MOSQ_ERR_SUCCESS) {
    g.pending.erase(id);
    throw ModelError("NotConnected", "cannot call " + where + ": not connected to the MQTT broker at " + g.settings.url_shown);
  }
  cv.wait_until(lock, after(g.call_timeout_s), [&] { return slot->done || act.cancelled(); });
  g.pending.erase(id);
  if (!slot->done) {
    if (act.cancelled()) throw Cancelled{};
    throw ModelError("CallTimeout", "no reply from " + where + " within " + fmt_g(g.call_timeout_s) + " s");
  }
  if (slot->lost) throw ModelError("NotConnected", "the connection to the MQTT broker was lost");
  const Value& reply = slot->reply;
  if (reply.contains("ok") && reply["ok"].is_boolean() && reply["ok"].get<bool>())
    return reply.contains("value") ? reply["value"] : Value();
  if (reply.contains("error") && reply["error"].is_object()) {
    const Value& error = reply["error"];
    auto text = [](const Value& v) { return v.is_string() ? v.get<std::string>() : dump(v); };
    std::string code = error.contains("code") ? text(error["code"]) : "internal";
    std::string message = error.contains("message") ? text(error["message"]) : "";
    throw ModelError("RemoteError", where + ": " + code + ": " + message);
  }
  throw ModelError("RemoteError", where + ": bad_reply: malformed reply: " + dump(reply).substr(0, 200));
}

Value Runtime::call_lane(Activation& caller, const char* lane, Walker walker, const NodeInfo* nodes, int start) {
  Activation act(lane, walker, nodes, &caller);
  act.run(start);
  return Value();
}

Value Runtime::sleep(Activation& act, const Value& seconds_value, double scale) {
  if (!is_num(seconds_value))
    throw ModelError("TypeError", std::string("float() argument must be a string or a real number, not '") + tname(seconds_value) + "'");
  if (g.opts.sim_clock) {
    const double seconds = std::max(0.0, as_dbl(seconds_value) * scale);
    std::unique_lock<std::mutex> lock(mu);
    if (act.cancelled()) throw Cancelled{};
    const uint64_t id = ++g.sim_next;
    g.sim_sleeping.insert(id);
    sim_publish("{\"sleep\":" + std::to_string(id) + ",\"s\":" + dump(Value(seconds)) + "}");
    sim_busy_locked(-1);
    cv.wait(lock, [&] { return g.sim_fired.count(id) > 0 || act.cancelled(); });
    if (!g.sim_fired.erase(id)) {  // cancelled before its wake: no longer a deadline of the sim's
      g.sim_sleeping.erase(id);
      sim_publish("{\"cancel\":" + std::to_string(id) + "}");
      sim_busy_locked(1);
      throw Cancelled{};
    }
    if (act.cancelled()) throw Cancelled{};
    return Value();
  }
  const double seconds = as_dbl(seconds_value) * scale / g.opts.speed;
  std::unique_lock<std::mutex> lock(mu);
  cv.wait_until(lock, after(std::max(0.0, seconds)), [&] { return act.cancelled(); });
  if (act.cancelled()) throw Cancelled{};
  return Value();
}

Value Runtime::exit_requested() const { return Value(g.exit_requested.load()); }

void Runtime::send(const char* signal, const Value& payload) {
  publish(g.base + "/signal/" + signal, dump(payload), 1, false);
}

Value Runtime::accept(Activation& act, const char* signal) {
  std::unique_lock<std::mutex> lock(mu);
  Board& board = g.boards[signal];
  if (board.held) {
    board.held = false;
    return std::move(board.held_value);
  }
  ++board.waiting;
  sim_busy_locked(-1);
  const uint64_t gen = board.gen;
  cv.wait(lock, [&] { return board.gen != gen || act.cancelled(); });
  --board.waiting;
  if (board.gen == gen) {  // not handed over by a signal: cancelled
    sim_busy_locked(1);
    throw Cancelled{};
  }
  return board.last;
}

void Runtime::trace(const char* lane, const NodeInfo& node, double start, double end, const Value* value,
                    const std::string* error, const std::string* warning) {
  if (!g.trace_on) return;
  std::string text = "{\"lane\":" + dump(lane) + ",\"node\":" + dump(node.id) + ",\"kind\":" + dump(node.kind) +
                     ",\"start\":" + dump(start) + ",\"end\":" + dump(end) +
                     ",\"duration_ms\":" + dump(std::round((end - start) * 1000.0 * 1000.0) / 1000.0);
  if (value != nullptr) text += ",\"value\":" + dump(*value);
  if (error != nullptr) {
    text += ",\"error\":" + dump(*error) + ",\"level\":\"error\",\"detail\":" + dump(node.label);
  } else if (warning != nullptr) {
    text += ",\"level\":\"warning\",\"detail\":" + dump(std::string(node.label) + ": " + *warning);
  } else {
    text += ",\"level\":\"info\",\"detail\":" + dump(node.label);
  }
  std::lock_guard<std::mutex> lock(mu);
  ++g.trace_recorded;
  text += ",\"seq\":" + std::to_string(g.trace_recorded) + "}";
  if (g.trace_pending.size() >= kTraceMaxPending) {
    g.trace_pending.pop_front();
    ++g.trace_dropped;
  }
  g.trace_pending.push_back(std::move(text));
  cv.notify_all();
}

// --- main ----------------------------------------------------------------------------------------

namespace {

const char* kUsage =
    "Usage: %s [OPTIONS]\n\n"
    "  Run the generated orchestrator of model %s (a drop-in for `umlbot run`).\n\n"
    "Options:\n"
    "  --broker URL             Broker URL, e.g. mqtt://user:pass@host:1883 (default: $UMLBOT_BROKER\n"
    "                           or mqtt://127.0.0.1:1883).\n"
    "  --ca-file FILE           CA certificate file for mqtts:// brokers.\n"
    "  --robot ID               Robot id (default: $UMLBOT_ROBOT or the model's name).\n"
    "  --call-timeout SECONDS   Seconds a feature call may take (default: the model's).\n"
    "  --trace FILE             Also write every trace event to FILE (JSON lines).\n"
    "  --no-trace               Do not publish trace events on MQTT.\n"
    "  --grace SECONDS          Seconds the lanes get to finish after an exit request [2].\n"
    "  --startup-timeout SECONDS  Seconds to wait for the used components to be online [10].\n"
    "  --log-level LEVEL        DEBUG, INFO, WARNING or ERROR [INFO].\n"
    "  --help                   Show this message and exit.\n";

double parse_seconds(const std::string& option, const std::string& text, double minimum) {
  char* end = nullptr;
  double value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(value) || value < minimum)
    throw UsageError("Invalid value for '" + option + "': '" + text + "' is not a number of seconds >= " + fmt_g(minimum));
  return value;
}

Options parse_options(int argc, char** argv, const ModelInfo& model, bool& help) {
  Options o;
  const char* env_broker = std::getenv("UMLBOT_BROKER");
  o.broker = env_broker && *env_broker ? env_broker : "mqtt://127.0.0.1:1883";
  const char* env_robot = std::getenv("UMLBOT_ROBOT");
  o.robot = env_robot && *env_robot ? env_robot : model.name;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    std::string value;
    bool inline_value = false;
    auto eq = arg.find('=');
    if (arg.compare(0, 2, "--") == 0 && eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
      inline_value = true;
    }
    auto take = [&]() -> std::string {
      if (inline_value) return value;
      if (i + 1 >= argc) throw UsageError("Option '" + arg + "' requires an argument.");
      return argv[++i];
    };
    if (arg == "--help" || arg == "-h") help = true;
    else if (arg == "--broker") o.broker = take();
    else if (arg == "--ca-file") o.ca_file = take();
    else if (arg == "--robot") o.robot = take();
    else if (arg == "--trace") o.trace_file = take();
    else if (arg == "--no-trace") o.trace = false;
    else if (arg == "--call-timeout") o.call_timeout_s = parse_seconds(arg, take(), 0.001);
    else if (arg == "--grace") o.grace_s = parse_seconds(arg, take(), 0);
    else if (arg == "--startup-timeout") o.startup_timeout_s = parse_seconds(arg, take(), 0);
    else if (arg == "--speed") o.speed = parse_seconds(arg, take(), 1e-9);
    else if (arg == "--sim-clock") o.sim_clock = true;
    else if (arg == "--log-level") {
      std::string level = take();
      std::transform(level.begin(), level.end(), level.begin(), ::toupper);
      if (level == "DEBUG") g_log_level = 10;
      else if (level == "INFO") g_log_level = 20;
      else if (level == "WARNING") g_log_level = 30;
      else if (level == "ERROR") g_log_level = 40;
      else throw UsageError("Invalid value for '--log-level': '" + level + "' is not one of 'DEBUG', 'INFO', 'WARNING', 'ERROR'.");
    } else if (arg == "--log-json" || arg == "--no-log-json") {
      // accepted for the same command line as `umlbot run`; lines stay plain text here
    } else throw UsageError("No such option: " + arg);
  }
  return o;
}

std::string random_hex(size_t bytes) {
  std::random_device rd;
  std::string out;
  const char* digits = "0123456789abcdef";
  for (size_t i = 0; i < bytes; ++i) {
    unsigned v = rd() & 0xFF;
    out += digits[v >> 4];
    out += digits[v & 15];
  }
  return out;
}

sigset_t g_signals;

void signal_thread() {
  while (true) {
    int signum = 0;
    if (sigwait(&g_signals, &signum) != 0) continue;
    if (signum == SIGUSR2) return;  // the program's own wake-up at its end
    Runtime& rt = runtime();
    std::lock_guard<std::mutex> lock(rt.mu);
    request_exit_locked(std::string(signum == SIGINT ? "SIGINT" : "SIGTERM") + " received");
  }
}

// libmosquitto's network thread ended (see network_thread_ends): join it, connect again, start it
// again, as its own reconnect does after a lost connection. Lock held on entry and on return.
void revive_network_locked(std::unique_lock<std::mutex>& lock) {
  g.loop_dead = false;
  lock.unlock();
  mosquitto_loop_stop(g.mosq, false);
  log_line(20, "mqtt_reconnecting", "reason=the broker ended the connection");
  int rc = mosquitto_reconnect_async(g.mosq);
  if (rc == MOSQ_ERR_SUCCESS) rc = mosquitto_loop_start(g.mosq);
  lock.lock();
  if (rc != MOSQ_ERR_SUCCESS) {
    g.loop_dead = true;  // the broker is not back yet: the next heartbeat tries again
    runtime().cv.wait_until(lock, after(1.0), [] { return g.heartbeat_stop; });
  }
}

void heartbeat_thread() {
  Runtime& rt = runtime();
  std::unique_lock<std::mutex> lock(rt.mu);
  for (uint64_t seq = 0; !g.heartbeat_stop; ++seq) {
    if (g.connected) {
      Value beat = Value::object();
      beat["reply_to"] = g.reply_topic;
      beat["seq"] = seq;
      beat["period_s"] = g.model->heartbeat_s;
      const std::string payload = dump(beat);
      publish_raw((g.base + "/orchestrator/heartbeat").c_str(),
                        static_cast<int>(payload.size()), payload.data(), 0, false);
    }
    if (g.loop_dead && !g.closing) revive_network_locked(lock);
    rt.cv.wait_until(lock, after(g.model->heartbeat_s), [] { return g.heartbeat_stop || g.loop_dead; });
  }
}

// The safe stops; at start every one (a failure is a start error), at the end the online ones.
void stop_actuators(bool at_start) {
  Runtime& rt = runtime();
  struct Pending { const SafeStop* stop; std::string id; std::shared_ptr<Slot> slot; };
  std::vector<Pending> calls;
  std::vector<std::string> skipped;
  const double timeout = at_start ? g.call_timeout_s : std::min(g.call_timeout_s, kFinalStopTimeoutS);
  {
    std::lock_guard<std::mutex> lock(rt.mu);
    for (const auto& stop : g.model->safe_stops) {
      if (!at_start && g.availability[stop.component] != "online") {
        skipped.push_back(stop.component);
        continue;
      }
      std::string id = g.id_prefix + std::to_string(++g.next_id);
      auto slot = std::make_shared<Slot>();
      g.pending[id] = slot;
      calls.push_back({&stop, id, slot});
    }
  }
  if (!skipped.empty()) log_line(30, "actuators offline, not stopped by the orchestrator");
  for (const auto& call : calls) {
    Value request = Value::object();
    request["id"] = call.id;
    request["reply_to"] = g.reply_topic;
    request["args"] = call.stop->args;
    request["timeout_s"] = timeout;
    const std::string payload = dump(request);
    const std::string topic = g.base + "/" + call.stop->component + "/call/" + call.stop->feature;
    publish_raw(topic.c_str(), static_cast<int>(payload.size()), payload.data(), 0, false);
  }
  std::unique_lock<std::mutex> lock(rt.mu);
  rt.cv.wait_until(lock, after(timeout), [&] {
    return std::all_of(calls.begin(), calls.end(), [](const Pending& p) { return p.slot->done; });
  });
  std::string failures;
  for (const auto& call : calls) {
    g.pending.erase(call.id);
    std::string where = std::string(call.stop->component) + "." + call.stop->feature;
    std::string problem;
    if (!call.slot->done) problem = "no reply from " + where + " within " + fmt_g(timeout) + " s";
    else if (call.slot->lost) problem = "the connection to the MQTT broker was lost";
    else if (!(call.slot->reply.contains("ok") && call.slot->reply["ok"] == true)) problem = dump(call.slot->reply);
    if (!problem.empty()) failures += (failures.empty() ? "" : "; ") + where + ": " + problem;
  }
  lock.unlock();
  if (!failures.empty() && at_start) throw StartError("cannot stop the actuators at start-up: " + failures);
  if (!failures.empty()) log_line(40, "actuator_stop_failed", failures);
  else log_line(20, "actuators_stopped");
}

std::string describe_missing(const std::vector<std::string>& missing) {
  std::string out;
  for (const auto& name : missing) {
    if (!out.empty()) out += ", ";
    auto state = g.availability.count(name) ? g.availability[name] : "no status";
    out += name + " (" + state + ")";
  }
  return out;
}

void wait_online() {
  Runtime& rt = runtime();
  std::unique_lock<std::mutex> lock(rt.mu);
  auto deadline = after(g.opts.startup_timeout_s);
  while (true) {
    if (g.failed || g.exit_requested_flag) return;
    std::vector<std::string> missing;
    for (const auto& c : g.model->required)
      if (g.availability[c] != "online") missing.push_back(c);
    if (missing.empty() && g.connected) return;
    if (Clock::now() >= deadline) {
      if (!g.connected)
        throw StartError("lost the connection to the MQTT broker at " + g.settings.url_shown +
                         " during start-up and it did not come back within " + fmt_g(g.opts.startup_timeout_s) + " s");
      throw StartError("component(s) not online after " + fmt_g(g.opts.startup_timeout_s) + " s: " + describe_missing(missing) +
                       " (robot '" + g.opts.robot + "', broker " + g.settings.url_shown +
                       "); start their services with `umlbot service KIND --deploy FILE`");
    }
    rt.cv.wait_until(lock, deadline);
  }
}

void run_lane(const ComponentLane& lane) {
  Runtime& rt = runtime();
  try {
    Activation act(lane.name, lane.walker, lane.nodes, nullptr);
    act.run(lane.start);
  } catch (const Cancelled&) {
  } catch (const NodeFailed& e) {
    std::lock_guard<std::mutex> lock(rt.mu);
    fail_locked(e.what(), false);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(rt.mu);
    fail_locked(std::string("lane ") + lane.name + ": internal error: " + e.what(), false);
  }
  std::lock_guard<std::mutex> lock(rt.mu);
  --g.lanes_running;
  sim_busy_locked(-1);
  rt.cv.notify_all();
}

void supervise() {
  Runtime& rt = runtime();
  std::vector<std::thread> threads;
  {
    std::lock_guard<std::mutex> lock(rt.mu);
    g.lanes_running = static_cast<int>(g.model->lanes.size());
    sim_busy_locked(g.lanes_running);
  }
  for (const auto& lane : g.model->lanes) threads.emplace_back(run_lane, std::cref(lane));
  {
    std::unique_lock<std::mutex> lock(rt.mu);
    while (true) {
      if (g.failed) break;
      if (g.lanes_running == 0) {
        log_line(20, "every lane ended");
        break;
      }
      if (g.has_deadline) {
        if (Clock::now() >= g.exit_deadline) {
          log_line(20, "grace period over: cancelling lanes");
          break;
        }
        rt.cv.wait_until(lock, g.exit_deadline);
      } else {
        rt.cv.wait(lock);
      }
    }
    rt.cancelled = true;
    g.exit_requested = true;
    rt.cv.notify_all();
  }
  for (auto& t : threads) t.join();
}

bool wait_connected(double seconds) {
  Runtime& rt = runtime();
  std::unique_lock<std::mutex> lock(rt.mu);
  return rt.cv.wait_until(lock, after(seconds), [] { return g.connected.load(); });
}

void wait_actuators_online(double seconds) {
  Runtime& rt = runtime();
  std::unique_lock<std::mutex> lock(rt.mu);
  rt.cv.wait_until(lock, after(seconds), [] {
    for (const auto& stop : g.model->safe_stops)
      if (g.availability[stop.component] != "online") return false;
    return true;
  });
}

}  // namespace

int run_main(int argc, char** argv, const ModelInfo& model) {
  // one malloc arena for all threads: a lane thread's own arena would keep its freed memory (the
  // values are small and short-lived; the lock costs nothing measurable at this rate)
  mallopt(M_ARENA_MAX, 1);
  g.model = &model;
  bool help = false;
  try {
    g.opts = parse_options(argc, argv, model, help);
  } catch (const UsageError& e) {
    std::fprintf(stderr, kUsage, argv[0], model.name);
    std::fprintf(stderr, "\nError: %s\n", e.what());
    return 2;
  }
  if (help) {
    std::printf(kUsage, argv[0], model.name);
    return 0;
  }
  try {
    g.settings = parse_url(g.opts.broker);
  } catch (const StartError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  if (!g.opts.ca_file.empty()) g.settings.ca = g.opts.ca_file;
  g.call_timeout_s = g.opts.call_timeout_s > 0 ? g.opts.call_timeout_s : model.call_timeout_s;
  g.base = "umlbot/" + g.opts.robot;
  const std::string token = random_hex(8);
  g.id_prefix = token.substr(0, 6) + "-";
  const std::string& user = g.settings.user;
  g.reply_topic = !user.empty() && user.find_first_of(std::string("/+#\0", 4)) == std::string::npos
                      ? g.base + "/_reply/" + user + "/" + token
                      : g.base + "/_reply/" + token;
  for (const auto& c : model.required) g.components.insert(c);
  for (const auto& s : model.safe_stops) g.components.insert(s.component);
  for (const auto& s : model.accepted) g.accepted.insert(s);
  g.trace_on = g.opts.trace || !g.opts.trace_file.empty();
  if (!g.opts.trace_file.empty()) {
    g.trace_out = std::fopen(g.opts.trace_file.c_str(), "w");
    if (g.trace_out == nullptr) {
      std::fprintf(stderr, "error: %s: cannot write the trace file\n", g.opts.trace_file.c_str());
      return 1;
    }
  }

  // SIGINT/SIGTERM go to one thread that requests the exit (a second one ends the grace)
  sigemptyset(&g_signals);
  sigaddset(&g_signals, SIGINT);
  sigaddset(&g_signals, SIGTERM);
  sigaddset(&g_signals, SIGUSR2);
  pthread_sigmask(SIG_BLOCK, &g_signals, nullptr);
  std::thread signals(signal_thread);

  Runtime& rt = runtime();
  mosquitto_lib_init();
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  const std::string client_id = "umlbot-orchestrator-" + g.opts.robot + "-" + host + "-" +
                                std::to_string(getpid()) + "-" + random_hex(16);
  g.mosq = mosquitto_new(client_id.substr(0, 200).c_str(), true, nullptr);
  g.mqtt5 = g.settings.protocol != "3.1.1";
  mosquitto_int_option(g.mosq, MOSQ_OPT_PROTOCOL_VERSION, g.mqtt5 ? MQTT_PROTOCOL_V5 : MQTT_PROTOCOL_V311);
  mosquitto_int_option(g.mosq, MOSQ_OPT_TCP_NODELAY, 1);
  if (!g.settings.user.empty())
    mosquitto_username_pw_set(g.mosq, g.settings.user.c_str(), g.settings.password.empty() ? nullptr : g.settings.password.c_str());
  if (g.settings.tls) {
    int rc = mosquitto_tls_set(g.mosq, g.settings.ca.empty() ? nullptr : g.settings.ca.c_str(),
                               g.settings.ca.empty() ? "/etc/ssl/certs" : nullptr,
                               g.settings.cert.empty() ? nullptr : g.settings.cert.c_str(),
                               g.settings.key.empty() ? nullptr : g.settings.key.c_str(), nullptr);
    if (rc != MOSQ_ERR_SUCCESS) {
      std::fprintf(stderr, "error: TLS settings of %s: %s\n", g.settings.url_shown.c_str(), mosquitto_strerror(rc));
      return 1;
    }
    if (g.settings.insecure) mosquitto_tls_insecure_set(g.mosq, true);
  }
  Value will = Value::object();
  will["state"] = "offline";
  will["reason"] = "orchestrator connection lost";
  will["model"] = model.name;
  const std::string will_text = dump(will);
  const std::string status_topic = g.base + "/orchestrator/status";
  mosquitto_will_set(g.mosq, status_topic.c_str(), static_cast<int>(will_text.size()), will_text.data(), 1, true);
  mosquitto_connect_callback_set(g.mosq, on_connect);
  mosquitto_disconnect_callback_set(g.mosq, on_disconnect);
  mosquitto_message_callback_set(g.mosq, on_message);
  mosquitto_publish_callback_set(g.mosq, on_publish);
  mosquitto_reconnect_delay_set(g.mosq, 1, 2, false);

  auto finish_threads = [&] { pthread_kill(signals.native_handle(), SIGUSR2); signals.join(); };
  auto started = Clock::now();
  // a broker that is not up yet (the robot booting) gets the connect time-out to come, as in Python
  const auto connect_deadline = after(kConnectTimeoutS);
  int rc = MOSQ_ERR_SUCCESS;
  std::string why;
  while (true) {
    rc = mosquitto_connect_async(g.mosq, g.settings.host.c_str(), g.settings.port, g.settings.keepalive);
    if (rc == MOSQ_ERR_SUCCESS) break;
    why = rc == MOSQ_ERR_ERRNO ? std::strerror(errno) : mosquitto_strerror(rc);
    bool give_up;
    {
      std::unique_lock<std::mutex> lock(rt.mu);
      give_up = rt.cv.wait_until(lock, std::min(connect_deadline, after(0.2)), [] { return g.exit_requested_flag; }) ||
                Clock::now() >= connect_deadline || rc == MOSQ_ERR_INVAL;
    }
    if (give_up) break;
  }
  if (rc == MOSQ_ERR_SUCCESS) rc = mosquitto_loop_start(g.mosq);
  bool up = false;
  if (rc == MOSQ_ERR_SUCCESS) {
    std::unique_lock<std::mutex> lock(rt.mu);
    g.connecting = true;
    rt.cv.wait_until(lock, connect_deadline, [] {
      return g.connected.load() || !g.connect_error.empty() || g.exit_requested_flag || g.fall_back;
    });
    if (g.fall_back && !g.exit_requested_flag) {
      // the broker refused MQTT 5 ("auto"): the same connection again, speaking 3.1.1 (the network
      // thread ended on the refusal); logged at debug level, as the Python side does
      lock.unlock();
      mosquitto_loop_stop(g.mosq, false);
      log_line(10, "mqtt_protocol_fallback", "broker=" + g.settings.url_shown + " protocol=3.1.1");
      g.mqtt5 = false;
      g.fall_back = false;
      g.loop_dead = false;
      mosquitto_int_option(g.mosq, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
      rc = mosquitto_connect_async(g.mosq, g.settings.host.c_str(), g.settings.port, g.settings.keepalive);
      if (rc == MOSQ_ERR_SUCCESS) rc = mosquitto_loop_start(g.mosq);
      lock.lock();
      if (rc != MOSQ_ERR_SUCCESS) g.connect_error = std::string("cannot connect again with MQTT 3.1.1: ") + mosquitto_strerror(rc);
      rt.cv.wait_until(lock, connect_deadline,
                       [] { return g.connected.load() || !g.connect_error.empty() || g.exit_requested_flag; });
    }
    up = g.connected;
    g.connecting = false;
    if (!up) why = g.connect_error.empty() ? "no answer within " + fmt_g(kConnectTimeoutS) + " s" : g.connect_error;
    if (!up && g.exit_requested_flag) {  // asked to end before the broker answered: nothing ran
      lock.unlock();
      mosquitto_disconnect(g.mosq);
      mosquitto_loop_stop(g.mosq, true);
      finish_threads();
      log_line(20, "orchestrator_finished", "exit_code=0");
      return 0;
    }
  }
  if (!up) {
    if (rc == MOSQ_ERR_SUCCESS) mosquitto_loop_stop(g.mosq, true);
    finish_threads();
    std::fprintf(stderr,
                 "error: cannot connect to the MQTT broker at %s within %s s (%s); is it running? "
                 "(umlbot broker, or --broker / UMLBOT_BROKER)\n",
                 g.settings.url_shown.c_str(), fmt_g(kConnectTimeoutS).c_str(), why.c_str());
    return 1;
  }
  std::thread trace(trace_thread);
  std::thread heartbeat(heartbeat_thread);
  std::string start_error;
  try {
    wait_online();
    bool go;
    {
      std::lock_guard<std::mutex> lock(rt.mu);
      go = !g.failed && !g.exit_requested_flag;
    }
    if (go) stop_actuators(true);
    {
      std::lock_guard<std::mutex> lock(rt.mu);
      go = !g.failed && !g.exit_requested_flag;
      if (go) enter_locked(Phase::Running, nullptr);
    }
    if (go) {
      log_line(20, "orchestrator_running", std::string("robot=") + g.opts.robot + " model=" + model.name);
      supervise();
    }
  } catch (const StartError& e) {
    start_error = e.what();
    std::lock_guard<std::mutex> lock(rt.mu);
    fail_locked(start_error, false);
  }
  // shutting down, on every path: stop the actuators, flush the trace, the final status
  rt.cancelled = true;
  g.exit_requested = true;
  if (!g.connected) {
    log_line(30, "waiting for the broker to stop the actuators");
    if (wait_connected(kReconnectWaitS)) wait_actuators_online(kActuatorsBackS);
    else log_line(40, "broker not back: actuators not stopped by the orchestrator (the motor services stop on their own when the broker is lost)");
  }
  if (g.connected) stop_actuators(false);
  {
    std::lock_guard<std::mutex> lock(rt.mu);
    g.trace_closing = true;
    rt.cv.notify_all();
  }
  trace.join();
  int code = 0;
  {
    std::lock_guard<std::mutex> lock(rt.mu);
    const std::string reason = g.failed ? g.fault : g.exit_requested_flag ? g.exit_reason : "every lane ended";
    enter_locked(g.failed ? Phase::Failed : Phase::Stopped, &reason);
    code = g.failed ? 1 : 0;
    g.heartbeat_stop = true;
    g.closing = true;
    rt.cv.notify_all();
  }
  heartbeat.join();
  {
    // the final status first reaches the broker (its PUBACK), then the DISCONNECT
    std::unique_lock<std::mutex> lock(rt.mu);
    rt.cv.wait_until(lock, after(1.0), [] { return g_final_acked.load() || !g.connected.load(); });
  }
  mosquitto_disconnect(g.mosq);
  {
    // the DISCONNECT must reach the broker before the network thread ends, else the broker
    // publishes the last will (`offline`) over the final status
    std::unique_lock<std::mutex> lock(rt.mu);
    rt.cv.wait_until(lock, after(1.0), [] { return !g.connected.load(); });
  }
  mosquitto_loop_stop(g.mosq, false);
  mosquitto_destroy(g.mosq);
  mosquitto_lib_cleanup();
  finish_threads();
  log_line(20, "orchestrator_finished", "exit_code=" + std::to_string(code) + " wall_s=" + fmt_g(elapsed(started)));
  if (!start_error.empty()) std::fprintf(stderr, "error: %s\n", start_error.c_str());
  else if (code != 0) std::fprintf(stderr, "error: fail-safe stop: %s\n", g.fault.c_str());
  return code;
}

}  // namespace umlbot
