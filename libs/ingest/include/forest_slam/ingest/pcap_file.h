#pragma once
// Classic libpcap capture files (tcpdump/Wireshark .pcap, microsecond or
// nanosecond stamps, either byte order), read record by record down to the
// UDP datagrams inside: what a Velodyne sends. Ethernet (with 802.1Q tags),
// Linux cooked (SLL) and raw-IP link types; IPv4 only, fragments skipped.
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
struct PcapUdpDatagram
{
	int64_t stamp_ns = 0;             ///< capture time, UNIX ns
	uint32_t src_ip = 0, dst_ip = 0;  ///< host byte order
	uint16_t src_port = 0, dst_port = 0;
	std::vector<uint8_t> payload;
};

class PcapFile
{
   public:
	/** Throws std::runtime_error naming the file if it cannot be opened or
	 * is not a classic pcap (pcapng is named as such). */
	explicit PcapFile(const std::string& path);

	/** Next UDP datagram; false at the end of the file. Other frames are
	 * skipped and counted. Throws std::runtime_error naming the file, the
	 * record index and byte offset if a record is truncated. */
	bool nextUdp(PcapUdpDatagram& out);

	uint64_t records() const { return records_; }
	uint64_t skipped() const { return skipped_; }
	uint32_t linkType() const { return link_type_; }

   private:
	std::string path_;
	std::ifstream in_;
	bool swap_ = false, nanos_ = false;
	uint32_t link_type_ = 0;
	uint64_t records_ = 0, skipped_ = 0;
	std::vector<uint8_t> frame_;
	uint32_t u32(const uint8_t* p) const;
	/** The UDP datagram in frame_, if it is one. */
	bool parseFrame(PcapUdpDatagram& out) const;
};

}  // namespace forest_slam::ingest
