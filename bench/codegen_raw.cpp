// The baseline of bench/codegen.py: a bare libmosquitto request/reply client (TCP_NODELAY) that
// sends the umlbot request envelope to a component service N times, one after the other, and
// prints each round trip in microseconds, one a line. It speaks MQTT 5 and subscribes with Retain
// As Published, as the generated program does (a fair baseline); `3.1.1` as a fifth argument
// speaks MQTT 3.1.1 instead.
//   g++ -O2 -std=c++17 codegen_raw.cpp -lmosquitto -o codegen_raw
//   codegen_raw HOST PORT ROBOT N [3.1.1]
#include <mosquitto.h>
#include <mqtt_protocol.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

static std::mutex mu;
static std::condition_variable cv;
static std::string expected;
static bool answered = false;
static bool connected = false;

static void on_connect(mosquitto*, void*, int rc) {
  std::lock_guard<std::mutex> lock(mu);
  connected = rc == 0;
  cv.notify_all();
}

static void on_message(mosquitto*, void*, const mosquitto_message* m) {
  std::string payload(static_cast<const char*>(m->payload), static_cast<size_t>(m->payloadlen));
  std::lock_guard<std::mutex> lock(mu);
  if (payload.find(expected) != std::string::npos) {
    answered = true;
    cv.notify_all();
  }
}

int main(int argc, char** argv) {
  if (argc != 5 && argc != 6) return 2;
  const bool mqtt5 = argc == 5 || std::string(argv[5]) != "3.1.1";
  const int n = std::atoi(argv[4]);
  const std::string robot = argv[3];
  const std::string reply = "umlbot/" + robot + "/_reply/bench-raw";
  const std::string topic = "umlbot/" + robot + "/LeftActuator/call/dutycycle";
  mosquitto_lib_init();
  mosquitto* m = mosquitto_new(nullptr, true, nullptr);
  mosquitto_int_option(m, MOSQ_OPT_TCP_NODELAY, 1);
  mosquitto_int_option(m, MOSQ_OPT_PROTOCOL_VERSION, mqtt5 ? MQTT_PROTOCOL_V5 : MQTT_PROTOCOL_V311);
  mosquitto_connect_callback_set(m, on_connect);
  mosquitto_message_callback_set(m, on_message);
  if (mosquitto_connect(m, argv[1], std::atoi(argv[2]), 30) != MOSQ_ERR_SUCCESS) return 1;
  mosquitto_loop_start(m);
  {
    std::unique_lock<std::mutex> lock(mu);
    if (!cv.wait_for(lock, std::chrono::seconds(5), [] { return connected; })) return 1;
  }
  int mid = 0;
  if (mqtt5) mosquitto_subscribe_v5(m, &mid, reply.c_str(), 0, MQTT_SUB_OPT_RETAIN_AS_PUBLISHED, nullptr);
  else mosquitto_subscribe(m, &mid, reply.c_str(), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the SUBACK
  for (int i = 0; i < n; ++i) {
    const std::string id = "r" + std::to_string(i);
    const std::string body = "{\"id\":\"" + id + "\",\"reply_to\":\"" + reply + "\",\"args\":[50],\"timeout_s\":5.0}";
    {
      std::lock_guard<std::mutex> lock(mu);
      expected = "\"" + id + "\"";
      answered = false;
    }
    auto began = std::chrono::steady_clock::now();
    mosquitto_publish(m, nullptr, topic.c_str(), static_cast<int>(body.size()), body.data(), 0, false);
    std::unique_lock<std::mutex> lock(mu);
    if (!cv.wait_for(lock, std::chrono::seconds(5), [] { return answered; })) return 1;
    auto took = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - began).count();
    std::printf("%.1f\n", took);
  }
  mosquitto_disconnect(m);
  mosquitto_loop_stop(m, false);
  return 0;
}
