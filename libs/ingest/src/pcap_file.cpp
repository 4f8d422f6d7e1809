#include <forest_slam/ingest/pcap_file.h>

#include <stdexcept>

namespace forest_slam::ingest
{
namespace
{
constexpr uint32_t kLinkEthernet = 1, kLinkRawIp = 101, kLinkRawIpAlt = 12,
                   kLinkRawIpAlt2 = 14, kLinkLinuxSll = 113;
uint16_t be16(const uint8_t* p)
{
	return static_cast<uint16_t>(p[0] << 8 | p[1]);
}
uint32_t be32(const uint8_t* p)
{
	return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 |
	       p[3];
}
}  // namespace

PcapFile::PcapFile(const std::string& path)
    : path_(path), in_(path, std::ios::binary)
{
	if (!in_) throw std::runtime_error("cannot open pcap '" + path + "'");
	uint8_t h[24];
	if (!in_.read(reinterpret_cast<char*>(h), sizeof(h)))
		throw std::runtime_error("'" + path +
		                         "' is too short for a pcap header");
	const uint32_t magic = uint32_t(h[3]) << 24 | uint32_t(h[2]) << 16 |
	                       uint32_t(h[1]) << 8 | h[0];
	if (magic == 0xa1b2c3d4)
	{
	}
	else if (magic == 0xd4c3b2a1)
		swap_ = true;
	else if (magic == 0xa1b23c4d)
		nanos_ = true;
	else if (magic == 0x4d3cb2a1)
		swap_ = nanos_ = true;
	else if (magic == 0x0a0d0d0a)
		throw std::runtime_error(
		    "'" + path +
		    "' is a pcapng file; save it as classic pcap (Wireshark: File > "
		    "Save As > pcap, or `editcap -F pcap IN OUT`)");
	else
		throw std::runtime_error("'" + path + "' is not a pcap file (magic " +
		                         std::to_string(magic) + ")");
	link_type_ = u32(h + 20) & 0x0fffffff;
	if (link_type_ != kLinkEthernet && link_type_ != kLinkRawIp &&
	    link_type_ != kLinkRawIpAlt && link_type_ != kLinkRawIpAlt2 &&
	    link_type_ != kLinkLinuxSll)
		throw std::runtime_error(
		    "'" + path + "': link type " + std::to_string(link_type_) +
		    " not supported (Ethernet, Linux SLL, raw IP)");
}

uint32_t PcapFile::u32(const uint8_t* p) const
{
	return swap_ ? be32(p)
	             : uint32_t(p[3]) << 24 | uint32_t(p[2]) << 16 |
	                   uint32_t(p[1]) << 8 | p[0];
}

bool PcapFile::nextUdp(PcapUdpDatagram& out)
{
	for (;;)
	{
		const auto offset = static_cast<uint64_t>(in_.tellg());
		uint8_t rh[16];
		if (!in_.read(reinterpret_cast<char*>(rh), sizeof(rh)))
		{
			if (in_.gcount() == 0) return false;
			throw std::runtime_error("'" + path_ + "': record " +
			                         std::to_string(records_) + " at byte " +
			                         std::to_string(offset) +
			                         " has a truncated header");
		}
		const uint32_t caplen = u32(rh + 8);
		if (caplen > (1u << 18))
			throw std::runtime_error("'" + path_ + "': record " +
			                         std::to_string(records_) + " at byte " +
			                         std::to_string(offset) + " claims " +
			                         std::to_string(caplen) + " bytes");
		frame_.resize(caplen);
		if (!in_.read(reinterpret_cast<char*>(frame_.data()), caplen))
			throw std::runtime_error("'" + path_ + "': record " +
			                         std::to_string(records_) + " at byte " +
			                         std::to_string(offset) + " is truncated");
		records_++;
		out.stamp_ns = int64_t(u32(rh)) * 1000000000LL +
		               int64_t(u32(rh + 4)) * (nanos_ ? 1 : 1000);
		if (parseFrame(out)) return true;
		skipped_++;
	}
}

bool PcapFile::parseFrame(PcapUdpDatagram& out) const
{
	const uint8_t* p = frame_.data();
	size_t n = frame_.size();
	auto skip = [&](size_t k)
	{
		if (n < k) return false;
		p += k;
		n -= k;
		return true;
	};
	if (link_type_ == kLinkEthernet)
	{
		if (n < 14) return false;
		uint16_t type = be16(p + 12);
		skip(14);
		while (type == 0x8100 || type == 0x88a8)  // VLAN tags
		{
			if (n < 4) return false;
			type = be16(p + 2);
			skip(4);
		}
		if (type != 0x0800) return false;
	}
	else if (link_type_ == kLinkLinuxSll)
	{
		if (n < 16 || be16(p + 14) != 0x0800) return false;
		skip(16);
	}
	// IPv4
	if (n < 20 || (p[0] >> 4) != 4) return false;
	const size_t ihl = size_t(p[0] & 0x0f) * 4;
	const size_t total = be16(p + 2);
	if (ihl < 20 || p[9] != 17 || (be16(p + 6) & 0x3fff) != 0) return false;
	if (total < ihl + 8 || total > n) return false;
	out.src_ip = be32(p + 12);
	out.dst_ip = be32(p + 16);
	n = total;
	skip(ihl);
	const size_t udp_len = be16(p + 4);
	if (udp_len < 8 || udp_len > n) return false;
	out.src_port = be16(p);
	out.dst_port = be16(p + 2);
	out.payload.assign(p + 8, p + udp_len);
	return true;
}

}  // namespace forest_slam::ingest
