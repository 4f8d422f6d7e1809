// forest-slam online fed by pcap-replay over loopback UDP (127.0.0.1 only,
// free ports picked at run time), stopped with SIGINT or SIGTERM; the same
// capture through the driver's pcap reader; the INI checks.
#include <forest_slam/core/config.h>
#include <forest_slam/ingest/pcap_file.h>
#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/online/online_config.h>
#include <forest_slam/online/raw_recorder.h>
#include <forest_slam/pipeline/mapping_job.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "process_helpers.h"

using namespace forest_slam;
using namespace online_test;
namespace fs = std::filesystem;

namespace
{
const std::string kPcap = std::string(FOREST_SLAM_SHARED_DIR) +
                          "/data/mrpt/sample_velodyne_vlp16_gps.pcap";
constexpr uint16_t kDataPort = 2368, kPositionPort = 8308;

/** Two UDP ports free on 127.0.0.1 right now (bound together, then freed). */
std::pair<int, int> freeUdpPorts()
{
	int s[2];
	int port[2];
	for (int i = 0; i < 2; i++)
	{
		s[i] = ::socket(AF_INET, SOCK_DGRAM, 0);
		sockaddr_in a{};
		a.sin_family = AF_INET;
		a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
		a.sin_port = 0;
		EXPECT_EQ(::bind(s[i], reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
		socklen_t len = sizeof(a);
		::getsockname(s[i], reinterpret_cast<sockaddr*>(&a), &len);
		port[i] = ntohs(a.sin_port);
	}
	::close(s[0]);
	::close(s[1]);
	return {port[0], port[1]};
}

/** The capture's data packets grouped into revolutions (a new one where
 * the azimuth goes down). The last one is still open when the stream stops:
 * our UDP receiver hands it over at SIGINT, MRPT's driver keeps it. */
std::vector<std::vector<std::vector<uint8_t>>> expectedRevolutions(
    bool with_open)
{
	ingest::PcapFile f(kPcap);
	ingest::PcapUdpDatagram d;
	std::vector<std::vector<std::vector<uint8_t>>> revs(1);
	int prev_azimuth = -1;
	while (f.nextUdp(d))
	{
		if (d.dst_port != kDataPort) continue;
		EXPECT_EQ(d.payload.size(), 1206u);
		const int azimuth = d.payload[2] | d.payload[3] << 8;
		if (prev_azimuth >= 0 && azimuth < prev_azimuth) revs.emplace_back();
		prev_azimuth = azimuth;
		revs.back().push_back(d.payload);
	}
	if (!with_open) revs.pop_back();
	return revs;
}

std::string liveIni(const std::string& dir, const std::string& velodyne_keys)
{
	const std::string ini = dir + "/live.ini";
	std::ofstream(ini)
	    << "[VLP16]\ndriver = CVelodyneScanner\nprocess_rate = 4000\n"
	       "sensorLabel = VLP16\nmodel = VLP16\n"
	       // PC clock stamps: the capture's GPS time (2016)
	       // would start once the first fix arrived, and
	       // the scans before would be ahead in time.
	       "pos_packets_timing_timeout = 0\n"
	    << velodyne_keys
	    << "\n[pipeline]\nlidar_label = VLP16_SCAN\n"
	       "gnss_label = VLP16_GPS\n\n[online]\nstatus_period_s = 0.5\n";
	return ini;
}

/** Checks raw.rawlog against the capture and the outputs against it. */
void checkRun(const std::string& ini, const std::string& out, bool interrupted,
              bool with_open)
{
	const auto expected = expectedRevolutions(with_open);
	ASSERT_GE(expected.size(), 3u);
	// 1. Every completed revolution is in raw.rawlog, packet for packet.
	io::RawlogReader raw(out + "/raw.rawlog");
	size_t scans = 0, gps = 0;
	while (auto o = raw.next())
	{
		if (auto v =
		        std::dynamic_pointer_cast<mrpt::obs::CObservationVelodyneScan>(
		            o))
		{
			EXPECT_EQ(v->sensorLabel, "VLP16_SCAN");
			ASSERT_LT(scans, expected.size())
			    << "more revolutions than the capture";
			const auto& want = expected[scans];
			ASSERT_EQ(v->scan_packets.size(), want.size())
			    << "revolution " << scans;
			for (size_t k = 0; k < want.size(); k++)
				EXPECT_EQ(
				    std::memcmp(&v->scan_packets[k], want[k].data(), 1206), 0)
				    << "revolution " << scans << " packet " << k;
			scans++;
		}
		else if (std::dynamic_pointer_cast<mrpt::obs::CObservationGPS>(o))
		{
			EXPECT_EQ(o->sensorLabel, "VLP16_GPS");
			gps++;
		}
	}
	EXPECT_FALSE(raw.damaged());
	EXPECT_EQ(scans, expected.size());
	EXPECT_GE(gps, 1u);
	// 2. One pose per processed scan; outputs complete and readable.
	const auto traj = io::readTum(out + "/trajectory.tum");
	EXPECT_EQ(traj.size(), scans);
	EXPECT_TRUE(pipeline::loadForestMap(out + "/forest.map"));
	const auto summary = slurp(out + "/run_summary.json");
	EXPECT_NE(summary.find("\"scans_in\": " + std::to_string(scans)),
	          std::string::npos)
	    << summary;
	EXPECT_NE(summary.find(std::string("\"interrupted\": ") +
	                       (interrupted ? "true" : "false")),
	          std::string::npos)
	    << summary;
	size_t packets = 0;
	for (const auto& rev : expected) packets += rev.size();
	const auto stats = slurp(out + "/online_stats.json");
	EXPECT_NE(
	    stats.find("\"velodyne_packets\": " + std::to_string(packets) + ","),
	    std::string::npos)
	    << stats;
	EXPECT_NE(stats.find("\"scans_dropped\": 0,"), std::string::npos) << stats;
	EXPECT_NE(stats.find("\"scans_processed\": " + std::to_string(scans)),
	          std::string::npos)
	    << stats;
	for (const auto& e : fs::directory_iterator(out))
		EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos)
		    << e.path();
	// 3. Re-mapping the recording offline with the same INI gives the same
	// trajectory (deterministic pipeline, nothing lost on the way).
	Child offline(
	    {bin("forest-slam"), "map", "--config", ini, "--rawlog",
	     out + "/raw.rawlog", "--out", out + "/offline", "--progress", "log"},
	    out + "/offline.log");
	ASSERT_EQ(offline.wait(200), 0) << offline.output();
	EXPECT_EQ(slurp(out + "/offline/trajectory.tum"),
	          slurp(out + "/trajectory.tum"));
}
}  // namespace

TEST(PcapFile, ReadsTheVelodyneCaptureDatagrams)
{
	ingest::PcapFile f(kPcap);
	ingest::PcapUdpDatagram d;
	int data = 0, position = 0;
	int64_t last = 0;
	while (f.nextUdp(d))
	{
		EXPECT_GE(d.stamp_ns, last);
		last = d.stamp_ns;
		if (d.dst_port == kDataPort)
		{
			data++;
			EXPECT_EQ(d.payload.size(), 1206u);
			EXPECT_EQ(d.payload[0], 0xff);  // block flag 0xEEFF
			EXPECT_EQ(d.payload[1], 0xee);
		}
		else if (d.dst_port == kPositionPort)
		{
			position++;
			EXPECT_EQ(d.payload.size(), 512u);
		}
	}
	EXPECT_EQ(data, 293);  // shared/data/README.md
	EXPECT_EQ(position, 57);
	EXPECT_EQ(f.skipped(), 0u);
	EXPECT_THROW(ingest::PcapFile("ini/sim-tiny.ini"), std::runtime_error);
}

namespace
{
/** Replays the capture over loopback UDP into `forest-slam online` with the
 * given receiver, stops it with `stop_signal`, checks everything. */
void loopbackRun(const std::string& name, const std::string& receiver,
                 double rate, bool with_open, int stop_signal)
{
	const auto dir = tempDir(name);
	const auto [data_port, position_port] = freeUdpPorts();
	const auto ini = liveIni(
	    dir, "udp_receiver = " + receiver +
	             "\nudp_data_port = " + std::to_string(data_port) +
	             "\nudp_position_port = " + std::to_string(position_port) +
	             "\n");
	const auto out = dir + "/out";
	Child online({bin("forest-slam"), "online", "--config", ini, "--out", out},
	             dir + "/online.log");
	ASSERT_TRUE(online.waitForOutput("grabbing at", 60)) << online.output();
	std::ostringstream r;
	r << rate;
	Child replay(
	    {bin("pcap-replay"), "--pcap", kPcap, "--rate", r.str(), "--host",
	     "127.0.0.1", "--data-port", std::to_string(data_port),
	     "--position-port", std::to_string(position_port)},
	    dir + "/replay.log");
	ASSERT_EQ(replay.wait(60), 0) << replay.output();
	EXPECT_NE(replay.output().find("sent 293 data + 57 position"),
	          std::string::npos)
	    << replay.output();
	// The completed revolutions are through once the status line says so.
	const auto n = std::to_string(expectedRevolutions(false).size());
	EXPECT_TRUE(online.waitForOutput("status: scans " + n + " (", 120))
	    << online.output();
	online.signal(stop_signal);
	ASSERT_EQ(online.wait(200), 0) << online.output();
	EXPECT_NE(online.output().find("signal " + std::to_string(stop_signal) +
	                               " received"),
	          std::string::npos)
	    << online.output();
	checkRun(ini, out, true, with_open);
}
}  // namespace

TEST(Online, LoopbackReplayThenSigintRecordsEveryPacket)
{
	// Our receiver: every packet, the open revolution included, even at
	// 3x the recorded rate (2260 packets/s, twice what MRPT's loop reads).
	loopbackRun("udp", "forest-slam", 3.0, true, SIGINT);
}

TEST(Online, LoopbackReplayThroughMrptReceiveLoopThenSigterm)
{
	// MRPT's own receive loop (about 1100 packets/s at most): half speed;
	// it keeps the open revolution. Stopped with SIGTERM this time.
	loopbackRun("udp_mrpt", "mrpt", 0.5, false, SIGTERM);
}

TEST(Online, DriverPcapReplayEndsByItself)
{
	const auto dir = tempDir("pcap");
	const auto ini = liveIni(dir, "pcap_input = " + kPcap +
	                                  "\npcap_read_once = true\n"
	                                  "pcap_read_fast = false\n"
	                                  "pcap_read_full_scan_delay_ms = 100\n");
	const auto out = dir + "/out";
	Child online({bin("forest-slam"), "online", "--config", ini, "--out", out},
	             dir + "/online.log");
	ASSERT_EQ(online.wait(200), 0) << online.output();
	EXPECT_NE(online.output().find("end of the replayed file"),
	          std::string::npos)
	    << online.output();
	checkRun(ini, out, false, false);
	// A second run into the same folder never overwrites the recording.
	Child again({bin("forest-slam"), "online", "--config", ini, "--out", out},
	            dir + "/again.log");
	EXPECT_EQ(again.wait(60), 1);
	EXPECT_NE(again.output().find("raw.rawlog' exists"), std::string::npos)
	    << again.output();
}

TEST(OnlineConfig, StrictAboutSensorKeysLabelsAndDrivers)
{
	const auto dir = tempDir("cfg");
	auto load = [&](const std::string& text)
	{
		std::ofstream(dir + "/c.ini") << text;
		return online::OnlineConfig::loadFile(dir + "/c.ini");
	};
	const std::string vlp =
	    "[VLP16]\ndriver = CVelodyneScanner\nprocess_rate = 2000\nsensorLabel "
	    "= VLP16\n";
	const auto ok = load(vlp + "[pipeline]\nlidar_label = VLP16_SCAN\n");
	ASSERT_EQ(ok.sensors.size(), 1u);
	EXPECT_EQ(ok.sensors[0].output_labels,
	          (std::vector<std::string>{"VLP16_SCAN", "VLP16_GPS"}));
	auto expectError = [&](const std::string& text, const std::string& needle)
	{
		try
		{
			load(text);
			ADD_FAILURE() << "no error for:\n" << text;
		}
		catch (const core::ConfigError& e)
		{
			EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
			    << e.what();
		}
	};
	expectError(vlp + "modle = VLP16\n[pipeline]\nlidar_label = VLP16_SCAN\n",
	            "'modle'");
	expectError(vlp + "[pipeline]\nlidar_label = lidar\n", "VLP16_SCAN");
	expectError(vlp +
	                "[online]\nqueue_capacity = 3\n[pipeline]\nlidar_label = "
	                "VLP16_SCAN\n",
	            "queue_capacity");
	expectError("[A]\ndriver = CNoSuchDriver\nprocess_rate = 1\n",
	            "CNoSuchDriver");
	expectError(
	    "[A]\ndriver = CVelodyneScanner\nsensorLabel = L\n[pipeline]\n"
	    "lidar_label = L_SCAN\n",
	    "process_rate");
	expectError("[pipeline]\nlidar_label = x\n", "no sensor section");
	// The shipped example loads (its sensor is only opened by start()).
	const auto shipped = online::OnlineConfig::loadFile("ini/live-vlp16.ini");
	ASSERT_EQ(shipped.sensors.size(), 1u);
	EXPECT_EQ(shipped.sensors[0].driver, "CVelodyneScanner");
	EXPECT_EQ(shipped.velodyne_data_port, 2368);
	EXPECT_NO_THROW(pipeline::MappingConfig::loadFile("ini/live-vlp16.ini"));
	// The offline mapping config accepts the same INI (re-runs of raw.rawlog).
	std::ofstream(dir + "/c.ini")
	    << vlp
	    << "[online]\nstatus_period_s = 2\n[pipeline]\n"
	       "lidar_label = VLP16_SCAN\n";
	EXPECT_NO_THROW(pipeline::MappingConfig::loadFile(dir + "/c.ini"));
}

TEST(OnlineCli, UsageErrorsExitTwo)
{
	const auto dir = tempDir("cli");
	auto run = [&](const std::vector<std::string>& args)
	{
		std::vector<std::string> argv{bin("forest-slam")};
		argv.insert(argv.end(), args.begin(), args.end());
		Child c(argv, dir + "/cli.log");
		const int code = c.wait(60);
		return std::make_pair(code, c.output());
	};
	EXPECT_EQ(run({"online", "--help"}).first, 0);
	auto r = run({"online", "--config", "ini/live-vlp16.ini"});
	EXPECT_EQ(r.first, 2);
	EXPECT_NE(r.second.find("--out"), std::string::npos) << r.second;
	r = run({"online", "--bogus"});
	EXPECT_EQ(r.first, 2);
	EXPECT_NE(r.second.find("--bogus"), std::string::npos) << r.second;
	r = run({"map", "--config", "ini/vlp16-handheld.ini", "--rawlog", "x",
	         "--out", dir, "--follow-timeout", "3"});
	EXPECT_EQ(r.first, 2);
	EXPECT_NE(r.second.find("--follow-timeout needs --follow"),
	          std::string::npos);
	r = run({"map", "--config", "ini/vlp16-handheld.ini", "--rawlog", "x",
	         "--out", dir, "--follow", "--follow-timeout", "-1"});
	EXPECT_EQ(r.first, 2);
	// A missing file while following is a runtime error naming it.
	r = run({"map", "--config", "ini/vlp16-handheld.ini", "--rawlog",
	         dir + "/never.rawlog", "--out", dir, "--follow",
	         "--follow-timeout", "0.3"});
	EXPECT_EQ(r.first, 1);
	EXPECT_NE(r.second.find("never.rawlog"), std::string::npos) << r.second;
}
