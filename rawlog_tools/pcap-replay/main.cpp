// pcap-replay: sends a Velodyne capture's UDP packets to a host (loopback by
// default) with their recorded timing, as the sensor would: data packets to
// the data port (2368), position packets to the position port (8308). For
// tests and demos of `forest-slam online` without a sensor.
#include <forest_slam/ingest/pcap_file.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

namespace
{
const char* kUsage =
    "usage: pcap-replay --pcap IN.pcap [--rate R] [--host IP]\n"
    "                   [--data-port N] [--position-port N] [--quiet]\n"
    "\n"
    "Sends the UDP packets of a Velodyne capture with their recorded timing\n"
    "(scaled by 1/R) to IP: packets captured to port 2368 (data) go to\n"
    "--data-port, those to port 8308 (position/GPS) to --position-port;\n"
    "other packets are skipped.\n"
    "\n"
    "  --pcap PATH         capture (classic libpcap format)\n"
    "  --rate R            replay speed, 1.0 = recorded timing, 5 = five "
    "times\n"
    "                      faster; 0 = as fast as possible (default 1.0)\n"
    "  --host IP           IPv4 destination (default 127.0.0.1)\n"
    "  --data-port N       default 2368\n"
    "  --position-port N   default 8308\n"
    "  --quiet             no summary\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error, 2 usage error.\n";

constexpr uint16_t kVelodyneDataPort = 2368, kVelodynePositionPort = 8308;
std::atomic<bool> g_stop{false};
extern "C" void onSignal(int)
{
	g_stop = true;
}

/** Later passes of --loop: the data packet's microsecond counter (bytes
 * 1200..1203, microseconds past the hour) moves on with the replay, so the
 * sensor's time never runs backwards between passes. */
void shiftSensorClock(std::vector<uint8_t>& packet, int64_t offset_ns)
{
	uint8_t* p = packet.data() + 1200;
	const uint64_t us = uint64_t(p[0]) | uint64_t(p[1]) << 8 |
	                    uint64_t(p[2]) << 16 | uint64_t(p[3]) << 24;
	const uint64_t shifted = (us + uint64_t(offset_ns / 1000)) % 3600000000ull;
	for (int i = 0; i < 4; i++) p[i] = uint8_t(shifted >> (8 * i));
}

int usageError(const std::string& msg)
{
	std::cerr << "pcap-replay: " << msg << "\n\n" << kUsage;
	return 2;
}

bool parsePort(const std::string& s, uint16_t& port)
{
	char* end = nullptr;
	const long v = std::strtol(s.c_str(), &end, 10);
	if (s.empty() || *end || v < 1 || v > 65535) return false;
	port = static_cast<uint16_t>(v);
	return true;
}
}  // namespace

int main(int argc, char** argv)
{
	std::string pcap, host = "127.0.0.1";
	double rate = 1.0;
	uint16_t data_port = kVelodyneDataPort, pos_port = kVelodynePositionPort;
	bool quiet = false;
	int loops = 1;
	const std::vector<std::string> args(argv + 1, argv + argc);
	for (size_t i = 0; i < args.size(); i++)
	{
		const std::string& a = args[i];
		const bool has_value = i + 1 < args.size();
		if (a == "--help" || a == "-h")
		{
			std::cout << kUsage;
			return 0;
		}
		else if (a == "--quiet")
			quiet = true;
		else if (!has_value)
			return usageError("unknown option or missing value: '" + a + "'");
		else if (a == "--pcap")
			pcap = args[++i];
		else if (a == "--host")
			host = args[++i];
		else if (a == "--rate")
		{
			char* end = nullptr;
			const std::string& v = args[++i];
			rate = std::strtod(v.c_str(), &end);
			if (v.empty() || *end || !std::isfinite(rate) || rate < 0)
				return usageError("--rate expects a number >= 0, got '" + v +
				                  "'");
		}
		else if (a == "--loop")
		{
			char* end = nullptr;
			const std::string& v = args[++i];
			const long n = std::strtol(v.c_str(), &end, 10);
			if (v.empty() || *end || n < 1 || n > 1000000)
				return usageError("--loop expects a count >= 1, got '" + v +
				                  "'");
			loops = static_cast<int>(n);
		}
		else if (a == "--data-port" || a == "--position-port")
		{
			if (!parsePort(args[++i],
			               a == "--data-port" ? data_port : pos_port))
				return usageError(a + " expects a port 1..65535, got '" +
				                  args[i] + "'");
		}
		else
			return usageError("unknown option '" + a + "'");
	}
	if (pcap.empty()) return usageError("--pcap is required");
	sockaddr_in dst{};
	dst.sin_family = AF_INET;
	if (inet_pton(AF_INET, host.c_str(), &dst.sin_addr) != 1)
		return usageError("--host expects an IPv4 address, got '" + host + "'");

	std::signal(SIGINT, onSignal);
	std::signal(SIGTERM, onSignal);
	try
	{
		const int sock = ::socket(AF_INET, SOCK_DGRAM, 0);
		if (sock < 0)
			throw std::runtime_error(std::string("socket: ") +
			                         std::strerror(errno));
		using Clock = std::chrono::steady_clock;
		forest_slam::ingest::PcapUdpDatagram d;
		uint64_t data = 0, position = 0, other = 0, skipped = 0;
		double max_late_ms = 0;
		int64_t first_ns = 0, last_ns = 0, loop_offset_ns = 0;
		bool first = true;
		const auto start = Clock::now();
		for (int pass = 0; pass < loops && !g_stop; pass++)
		{
			forest_slam::ingest::PcapFile file(pcap);
			// Each pass starts one 10 ms step after the previous one ended.
			if (pass > 0) loop_offset_ns += last_ns - first_ns + 10000000;
			while (!g_stop && file.nextUdp(d))
			{
				uint16_t port = 0;
				if (d.dst_port == kVelodyneDataPort)
					port = data_port;
				else if (d.dst_port == kVelodynePositionPort)
					port = pos_port;
				else
				{
					other++;
					continue;
				}
				if (first) first_ns = d.stamp_ns, first = false;
				if (pass == 0) last_ns = d.stamp_ns;
				if (rate > 0)
				{
					const auto due =
					    start +
					    std::chrono::nanoseconds(static_cast<int64_t>(
					        (d.stamp_ns - first_ns + loop_offset_ns) / rate));
					std::this_thread::sleep_until(due);
					max_late_ms = std::max(
					    max_late_ms, std::chrono::duration<double, std::milli>(
					                     Clock::now() - due)
					                     .count());
				}
				if (pass > 0 && port == data_port && d.payload.size() == 1206)
					shiftSensorClock(d.payload, loop_offset_ns);
				dst.sin_port = htons(port);
				if (::sendto(sock, d.payload.data(), d.payload.size(), 0,
				             reinterpret_cast<const sockaddr*>(&dst),
				             sizeof(dst)) < 0)
					throw std::runtime_error("sendto " + host + ":" +
					                         std::to_string(port) + ": " +
					                         std::strerror(errno));
				(port == data_port ? data : position)++;
			}
			skipped += file.skipped();
		}
		::close(sock);
		if (!quiet)
			std::printf(
			    "pcap-replay: sent %llu data + %llu position packets to %s in "
			    "%.2f s (rate %g, latest packet %.1f ms behind schedule); %llu "
			    "other UDP + %llu non-UDP records skipped%s\n",
			    (unsigned long long)data, (unsigned long long)position,
			    host.c_str(),
			    std::chrono::duration<double>(Clock::now() - start).count(),
			    rate, max_late_ms, (unsigned long long)other,
			    (unsigned long long)skipped, g_stop ? " (interrupted)" : "");
		return 0;
	}
	catch (const std::exception& e)
	{
		std::cerr << "pcap-replay: " << e.what() << "\n";
		return 1;
	}
}
