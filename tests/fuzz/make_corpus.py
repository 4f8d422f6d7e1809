#!/usr/bin/env python3
"""Writes the seed corpus of the fuzz targets (tests/fuzz/corpus/<target>/).
Seeds are small valid inputs (plus a few cut ones) built from the shared real
data and the shipped INIs, so that the fuzzer starts from every code path of
the readers. Run from the repository root: python3 tests/fuzz/make_corpus.py
"""
import os
import struct

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "data")
OUT = os.path.join(ROOT, "tests", "fuzz", "corpus")


def write(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


# ---- LAS -------------------------------------------------------------------
def las_seeds():
    pine = open(os.path.join(SHARED, "treels", "pine.las"), "rb").read()
    off = struct.unpack_from("<I", pine, 96)[0]
    rec = struct.unpack_from("<H", pine, 105)[0]
    hdr = bytearray(pine[:off])
    struct.pack_into("<I", hdr, 107, 6)
    las12 = bytes(hdr) + pine[off:off + 6 * rec]
    write("las", "pine_6_points_v12_f0.las", las12)
    write("las", "pine_cut_mid_record.las", las12[: len(las12) - rec // 2])
    # LAS 1.4, point format 6 (30-byte records), 3 points.
    h = bytearray(375)
    h[0:4] = b"LASF"
    h[24], h[25] = 1, 4
    struct.pack_into("<H", h, 94, 375)
    struct.pack_into("<I", h, 96, 375)
    h[104] = 6
    struct.pack_into("<H", h, 105, 30)
    for i in range(3):
        struct.pack_into("<d", h, 131 + 8 * i, 0.001)
        struct.pack_into("<d", h, 155 + 8 * i, 100.0 * i)
    struct.pack_into("<Q", h, 247, 3)
    pts = b""
    for k in range(3):
        p = bytearray(30)
        struct.pack_into("<iiiH", p, 0, 1000 * k, -2000 * k, 300 * k, 7 * k)
        p[16] = 2
        struct.pack_into("<h", p, 18, 100 * k)
        struct.pack_into("<d", p, 22, 1.5e8 + k)
        pts += bytes(p)
    write("las", "three_points_v14_f6.las", bytes(h) + pts)


# ---- ROS messages ----------------------------------------------------------
class W:
    """ROS 1 (no alignment) or CDR little endian (aligned to the element
    size, relative to the byte after the 4-byte encapsulation header)."""

    def __init__(self, cdr):
        self.cdr = cdr
        self.b = bytearray(b"\x00\x01\x00\x00" if cdr else b"")
        self.origin = len(self.b)

    def align(self, n):
        if self.cdr:
            while (len(self.b) - self.origin) % n:
                self.b.append(0)

    def p(self, fmt, *v):
        self.align(struct.calcsize("<" + fmt[0]))
        self.b += struct.pack("<" + fmt, *v)

    def string(self, s):
        raw = s.encode() + (b"\x00" if self.cdr else b"")
        self.p("I", len(raw))
        self.b += raw

    def header(self, sec, nsec, frame):
        if not self.cdr:
            self.p("I", 7)  # seq
        self.p("i" if self.cdr else "I", sec)
        self.p("I", nsec)
        self.string(frame)


def cloud(cdr, fields, point_step, points):
    w = W(cdr)
    w.header(1700000000, 5000, "velodyne")
    w.p("I", 1)
    w.p("I", len(points))
    w.p("I", len(fields))
    for name, off, dt in fields:
        w.string(name)
        w.p("I", off)
        w.p("B", dt)
        w.p("I", 1)
    w.p("B", 0)
    w.p("I", point_step)
    w.p("I", point_step * len(points))
    data = b"".join(points)
    w.p("I", len(data))
    w.b += data
    w.p("B", 1)
    return bytes(w.b)


def imu(cdr):
    w = W(cdr)
    w.header(1700000000, 123, "imu_link")
    for v in [0, 0, 0, 1] + [0.0] * 9 + [0.01, 0.02, -0.03] + [0.0] * 9 + [0.1, -0.2, 9.81] + [0.0] * 9:
        w.p("d", v)
    return bytes(w.b)


def navsat(cdr):
    w = W(cdr)
    w.header(1700000000, 0, "gnss")
    w.p("b", 0)
    w.p("H", 1)
    for v in [59.66, 10.77, 95.0] + [0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.04]:
        w.p("d", v)
    w.p("B", 2)
    return bytes(w.b)


def tf(cdr):
    w = W(cdr)
    w.p("I", 2)
    for child in ("velodyne", "imu_link"):
        w.header(1700000000, 0, "base_link")
        w.string(child)
        for v in [0.1, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]:
            w.p("d", v)
    return bytes(w.b)


def velodyne_packets():
    """The first two 1206-byte data packets of the VLP-16 sample capture."""
    d = open(os.path.join(SHARED, "mrpt", "sample_velodyne_vlp16_gps.pcap"), "rb").read()
    pos, out = 24, []
    while pos + 16 <= len(d) and len(out) < 2:
        incl = struct.unpack_from("<I", d, pos + 8)[0]
        frame = d[pos + 16: pos + 16 + incl]
        pos += 16 + incl
        if len(frame) >= 42 + 1206 and struct.unpack_from(">H", frame, 36)[0] == 2368:
            out.append(frame[42: 42 + 1206])
    return out


def velodyne_scan(cdr, packets):
    w = W(cdr)
    w.header(1700000000, 0, "velodyne")
    w.p("I", len(packets))
    for i, p in enumerate(packets):
        w.p("i" if cdr else "I", 1700000000)
        w.p("I", 1000 * i)
        w.b += p
    return bytes(w.b)


def ros_seeds():
    vel_fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7),
                  ("ring", 16, 4), ("time", 18, 7)]
    vel_pts = [struct.pack("<ffffHf", 1.0 + i, 2.0, -0.5, 10.0, i % 16, 0.001 * i) for i in range(4)]
    vel_pts.append(struct.pack("<ffffHf", float("nan"), 0, 0, 0, 0, 0))
    ouster_fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("t", 12, 6), ("ring", 16, 2)]
    ouster_pts = [struct.pack("<fffIBxxx", 3.0, -1.0, 0.2, 100000 * i, i) for i in range(3)]
    hesai_fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("timestamp", 16, 8), ("ring", 24, 4)]
    hesai_pts = [struct.pack("<fffxxxxdHxx", 1.0, 1.0, 1.0, 1700000000.0 + 0.01 * i, i) for i in range(3)]
    packets = velodyne_packets()
    for cdr in (False, True):
        wire = 1 if cdr else 0
        tag = "cdr" if cdr else "ros1"
        sel = lambda kind: bytes([wire | (kind << 1)])
        write("ros_messages", f"cloud_velodyne_{tag}", sel(0) + cloud(cdr, vel_fields, 22, vel_pts))
        write("ros_messages", f"cloud_ouster_{tag}", sel(0) + cloud(cdr, ouster_fields, 20, ouster_pts))
        write("ros_messages", f"cloud_hesai_{tag}", sel(0) + cloud(cdr, hesai_fields, 28, hesai_pts))
        write("ros_messages", f"imu_{tag}", sel(1) + imu(cdr))
        write("ros_messages", f"navsatfix_{tag}", sel(2) + navsat(cdr))
        write("ros_messages", f"tf_{tag}", sel(3) + tf(cdr))
        write("ros_messages", f"velodyne_scan_{tag}", sel(4) + velodyne_scan(cdr, packets))


# ---- INI -------------------------------------------------------------------
def ini_seeds():
    for name in ("vlp16-handheld.ini", "vlp16-robot.ini"):
        write("ini", name, open(os.path.join(ROOT, "ini", name), "rb").read())
    write("ini", "small.ini", b"[pipeline]\npose_source = static\nmax_scans = 3\n"
          b"[forest_map]\n[odometry]\n[trees]\nlayer_enabled = false\n")
    write("ini", "bad_value.ini", b"[pipeline]\nmin_range_m = abc\n")


if __name__ == "__main__":
    las_seeds()
    ros_seeds()
    ini_seeds()
