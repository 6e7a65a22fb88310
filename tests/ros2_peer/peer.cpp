// An independent ROS 2 peer for umlbot's tests: eProsima Fast DDS (ROS 2's default DDS), with no
// generated types. Every topic carries raw CDR bytes (encapsulation header included) under the
// DDS type name it is given, so the test encodes and decodes the messages with rosbags and this
// program only moves them. Loopback only: UDPv4 on 127.0.0.1, no multicast, peer 127.0.0.1.
//
// usage: peer DOMAIN_ID; commands on stdin, one a line:
//   sub TOPIC TYPE          -> prints "msg TOPIC HEX" for every sample received
//   pub TOPIC TYPE HEX      -> writes one sample (the writer is made once per topic)
//   wait TOPIC N            -> prints "matched TOPIC" once the writer of TOPIC has N readers
//   quit
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include <chrono>
#include <cstring>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::SerializedPayload_t;
using eprosima::fastrtps::rtps::InstanceHandle_t;

static std::mutex out_mutex;

static void say(const std::string& line) {
    std::lock_guard<std::mutex> lock(out_mutex);
    std::cout << line << std::endl;
}

struct Raw {
    std::vector<unsigned char> bytes;
};

class RawType : public TopicDataType {
public:
    explicit RawType(const std::string& name) {
        setName(name.c_str());
        m_typeSize = 65536;
        m_isGetKeyDefined = false;
    }
    bool serialize(void* data, SerializedPayload_t* payload) override {
        auto* raw = static_cast<Raw*>(data);
        if (raw->bytes.size() > payload->max_size) return false;
        std::memcpy(payload->data, raw->bytes.data(), raw->bytes.size());
        payload->length = static_cast<uint32_t>(raw->bytes.size());
        payload->encapsulation = raw->bytes.size() > 1 && raw->bytes[1] == 1 ? CDR_LE : CDR_BE;
        return true;
    }
    bool deserialize(SerializedPayload_t* payload, void* data) override {
        auto* raw = static_cast<Raw*>(data);
        raw->bytes.assign(payload->data, payload->data + payload->length);
        return true;
    }
    std::function<uint32_t()> getSerializedSizeProvider(void* data) override {
        return [data]() { return static_cast<uint32_t>(static_cast<Raw*>(data)->bytes.size()); };
    }
    void* createData() override { return new Raw(); }
    void deleteData(void* data) override { delete static_cast<Raw*>(data); }
    bool getKey(void*, InstanceHandle_t*, bool) override { return false; }
};

static std::string hex(const std::vector<unsigned char>& bytes) {
    static const char* digits = "0123456789abcdef";
    std::string out;
    for (unsigned char b : bytes) { out += digits[b >> 4]; out += digits[b & 15]; }
    return out;
}

static std::vector<unsigned char> unhex(const std::string& text) {
    std::vector<unsigned char> out;
    for (size_t i = 0; i + 1 < text.size(); i += 2) out.push_back(std::stoi(text.substr(i, 2), nullptr, 16));
    return out;
}

class Printer : public DataReaderListener {
public:
    explicit Printer(std::string topic) : topic_(std::move(topic)) {}
    void on_data_available(DataReader* reader) override {
        Raw raw;
        SampleInfo info;
        while (reader->take_next_sample(&raw, &info) == ReturnCode_t::RETCODE_OK) {
            if (info.valid_data) say("msg " + topic_ + " " + hex(raw.bytes));
        }
    }
private:
    std::string topic_;
};

int main(int argc, char** argv) {
    int domain = argc > 1 ? std::atoi(argv[1]) : 0;
    DomainParticipantQos pqos;
    pqos.name("umlbot_fastdds_peer");
    pqos.transport().use_builtin_transports = false;
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    pqos.transport().user_transports.push_back(udp);
    eprosima::fastrtps::rtps::Locator_t peer;
    eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, "127.0.0.1");
    pqos.wire_protocol().builtin.initialPeersList.push_back(peer);
    pqos.wire_protocol().builtin.discovery_config.leaseDuration_announcementperiod = {0, 200000000};
    eprosima::fastrtps::rtps::Locator_t meta;  // unicast metatraffic on loopback: no multicast
    eprosima::fastrtps::rtps::IPLocator::setIPv4(meta, "127.0.0.1");
    pqos.wire_protocol().builtin.metatrafficUnicastLocatorList.push_back(meta);
    pqos.wire_protocol().default_unicast_locator_list.push_back(meta);
    DomainParticipant* participant = DomainParticipantFactory::get_instance()->create_participant(domain, pqos);
    if (participant == nullptr) { say("error participant"); return 1; }
    Publisher* publisher = participant->create_publisher(PUBLISHER_QOS_DEFAULT);
    Subscriber* subscriber = participant->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
    std::map<std::string, Topic*> topics;
    std::map<std::string, DataWriter*> writers;
    std::vector<std::unique_ptr<Printer>> printers;

    auto topic_of = [&](const std::string& name, const std::string& type) -> Topic* {
        auto found = topics.find(name);
        if (found != topics.end()) return found->second;
        TypeSupport support(new RawType(type));
        support.register_type(participant);
        Topic* topic = participant->create_topic(name, type, TOPIC_QOS_DEFAULT);
        topics[name] = topic;
        return topic;
    };

    say("ready");
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd, name, type, data;
        in >> cmd;
        if (cmd == "quit") break;
        if (cmd == "sub") {
            in >> name >> type;
            DataReaderQos rqos = DATAREADER_QOS_DEFAULT;
            rqos.reliability().kind = BEST_EFFORT_RELIABILITY_QOS;  // matches every writer
            printers.push_back(std::make_unique<Printer>(name));
            subscriber->create_datareader(topic_of(name, type), rqos, printers.back().get());
            say("subscribed " + name);
        } else if (cmd == "pub") {
            in >> name >> type >> data;
            if (!writers.count(name)) {
                DataWriterQos wqos = DATAWRITER_QOS_DEFAULT;
                wqos.reliability().kind = RELIABLE_RELIABILITY_QOS;
                writers[name] = publisher->create_datawriter(topic_of(name, type), wqos);
            }
            Raw raw{unhex(data)};
            say(writers[name]->write(&raw) ? "published " + name : "error write " + name);
        } else if (cmd == "wait") {
            size_t count = 0;
            in >> name >> count;
            if (!writers.count(name)) { say("error no writer " + name); continue; }
            for (int i = 0; i < 500; ++i) {
                PublicationMatchedStatus status;
                writers[name]->get_publication_matched_status(status);
                if (static_cast<size_t>(status.current_count) >= count) { say("matched " + name); break; }
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
            }
        }
    }
    participant->delete_contained_entities();
    DomainParticipantFactory::get_instance()->delete_participant(participant);
    return 0;
}
