// umlbot runtime for generated orchestrators (C++17): MQTT over libmosquitto, JSON values with
// nlohmann-json, the request/reply envelope, trace batching, retained status, the heartbeat that
// keeps the motors' lease, and the fail-safe stops. Copied verbatim into every generated project
// by `umlbot generate cpp`; the generated model.cpp holds the swimlanes and calls only this API.
//
// Threads: one per component lane and one per fork token (a virtual lane runs on its caller's
// thread); every wait (reply, sleep, signal, join) waits on one condition variable with a
// predicate that also sees the activation's and the run's cancellation, so an end node, a fault
// or the grace period's end unwinds every thread at its next wait or node.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace umlbot {

using Value = nlohmann::json;

// --- errors: the name is what the trace shows before the message (as the interpreter does) -------

struct ModelError : std::runtime_error {
  std::string type;
  ModelError(std::string type_name, const std::string& message)
      : std::runtime_error(message), type(std::move(type_name)) {}
};

// Thrown through a thread when its activation or the run ends: never traced, never a fault.
struct Cancelled {};

// A node raised: the message is the fault reason ("lane L, node N (label): cause").
struct NodeFailed : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// --- the expression language's operators, with the interpreter's (Python's) semantics -------------

bool truthy(const Value& v);
Value op_add(const Value& a, const Value& b);
Value op_sub(const Value& a, const Value& b);
Value op_mul(const Value& a, const Value& b);
Value op_div(const Value& a, const Value& b);
Value op_mod(const Value& a, const Value& b);
Value op_eq(const Value& a, const Value& b);
Value op_ne(const Value& a, const Value& b);
Value op_lt(const Value& a, const Value& b);
Value op_le(const Value& a, const Value& b);
Value op_gt(const Value& a, const Value& b);
Value op_ge(const Value& a, const Value& b);
Value op_not(const Value& a);
Value op_neg(const Value& a);

// --- datastores --------------------------------------------------------------------------------

// A lane's datastore: one model value, safe to read and write from every lane's threads. Reads
// null until written (as the interpreter's).
class Datastore {
 public:
  explicit Datastore(const char* name) : name_(name) {}
  Value get() const;
  void set(Value value);
  const char* name() const { return name_; }

 private:
  const char* name_;
  mutable std::mutex mu_;
  Value value_;
};

// --- activations: one run of a lane, its fork tokens and its join counts --------------------------

class Activation;
enum class Outcome { Ended, Stopped, Forked };
using Walker = Outcome (*)(Activation&, int node, int prev);

// What the generated code knows of a node: for traces and fault reasons.
struct NodeInfo {
  const char* id;
  const char* kind;
  const char* label;
};

class Activation {
 public:
  Activation(const char* lane, Walker walker, const NodeInfo* nodes, Activation* parent);
  ~Activation();
  Activation(const Activation&) = delete;
  Activation& operator=(const Activation&) = delete;

  // Walk from `start` until the activation ends (joins every token); rethrows a token's failure.
  void run(int start);
  // True once this activation or one that called it (or the whole run) is cancelled.
  bool cancelled() const;
  // Throws Cancelled when cancelled (each node starts with it).
  void checkpoint() const;

  // A fork: trace it and start one token per target.
  Outcome fork(int node, std::initializer_list<int> targets);
  // A join: counts the flow from `prev`; true for the flow that continues (the last to arrive).
  bool arrive(int join, int prev, std::initializer_list<int> incoming);

  // Run a node's function, trace the node with its value and return it; on an exception, trace
  // the error and throw NodeFailed (Cancelled and NodeFailed pass through).
  Value step(int node, Value (*body)(Activation&));
  // The trace of a node without a body (start, end, fork, join).
  void passed(int node);
  // A decision: `choose` returns the target node (its id is the traced value) or -1 when no
  // guard holds and there is no else (a warning; the flow stops).
  int decide(int node, int (*choose)(Activation&));

  const char* lane() const { return lane_; }
  const NodeInfo& info(int node) const { return nodes_[node]; }

 private:
  friend class Runtime;
  void token(int target, int from);
  void cancel_tokens();
  [[noreturn]] void failed(int node, double began, const char* type, const std::string& message);
  // In a catch block: trace the exception being handled as the node's error and throw NodeFailed
  // (Cancelled and NodeFailed pass through).
  [[noreturn]] void fail_current(int node, double began);
  void traced(int node, double began, const Value* value, const std::string* warning);

  const char* lane_;
  Walker walker_;
  const NodeInfo* nodes_;
  Activation* parent_;
  std::atomic<bool> cancelled_{false};
  std::vector<std::thread> threads_;
  int live_ = 0;          // tokens running (guarded by the runtime's mutex)
  bool finished_ = false; // an end reached, or no token left
  bool waiting_ = false;  // run() waits for the tokens (guarded by the runtime's mutex)
  std::exception_ptr failure_;
  std::map<std::pair<int, int>, int> arrivals_;
};

// --- the runtime: connection, calls, signals, trace, status, life --------------------------------

struct SafeStop {
  const char* component;
  const char* feature;
  Value args;
};

struct ComponentLane {
  const char* name;
  Walker walker;
  const NodeInfo* nodes;
  int start;
};

// What the generated model gives the runtime.
struct ModelInfo {
  const char* name;
  const char* source_hash;
  double call_timeout_s;
  double heartbeat_s;
  std::vector<std::string> required;    // components that must be online (used + actuators)
  std::vector<SafeStop> safe_stops;     // in component name order
  std::vector<std::string> accepted;    // signal names accept nodes wait for
  std::vector<ComponentLane> lanes;     // component lanes, name order
};

double now();  // unix seconds, wall clock

class Runtime {
 public:
  // Feature call: one request/reply with the run's time-out (CallTimeout, RemoteError, NotConnected).
  Value call(Activation& act, const char* component, const char* feature, Value args);
  // A virtual lane: a new activation on this thread.
  Value call_lane(Activation& caller, const char* lane, Walker walker, const NodeInfo* nodes, int start);
  // usleep/msleep: seconds of wall time (of the simulator's clock with --sim-clock), cut short by
  // cancellation.
  Value sleep(Activation& act, const Value& seconds_value, double scale);
  // Application.exit
  Value exit_requested() const;
  // A send node: publish the signal with its payload (JSON).
  void send(const char* signal, const Value& payload);
  // An accept node: the payload of the next occurrence (a held one first).
  Value accept(Activation& act, const char* signal);

  // the trace (called by Activation)
  void trace(const char* lane, const NodeInfo& node, double start, double end, const Value* value,
             const std::string* error, const std::string* warning);

  // One lock and one condition for every wait: replies, sleeps, signals, tokens, the supervisor.
  std::mutex mu;
  std::condition_variable cv;
  // The run is ending: every activation is cancelled.
  std::atomic<bool> cancelled{false};
};

Runtime& runtime();

// The program's main: options, connect, wait online, stop actuators, run lanes, stop, exit code.
int run_main(int argc, char** argv, const ModelInfo& model);

}  // namespace umlbot
