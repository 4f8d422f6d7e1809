#include <forest_slam/eval/json_writer.h>
#include <forest_slam/eval/svg_plot.h>
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

using namespace forest_slam::eval;

TEST(JsonWriter, NestingNullsAndEscapes)
{
	std::ostringstream os;
	JsonWriter j(os);
	j.beginObject();
	j.kv("a", 1.5).kv("nan", std::nan("")).kv("s", "q\"\\\n");
	j.key("arr").beginArray().value(1).value(true).null().endArray();
	j.key("empty").beginObject().endObject();
	j.endObject();
	EXPECT_EQ(os.str(),
	          "{\n  \"a\": 1.5,\n  \"nan\": null,\n  \"s\": \"q\\\"\\\\\\n\",\n"
	          "  \"arr\": [\n    1,\n    true,\n    null\n  ],\n  \"empty\": "
	          "{}\n}\n");
	std::ostringstream bad;
	JsonWriter b(bad);
	b.beginObject();
	EXPECT_THROW(b.value(1.0), std::logic_error);  // value without a key
	EXPECT_THROW(b.endArray(), std::logic_error);
}

TEST(JsonWriter, KeepsTimestampDigits)
{
	std::ostringstream os;
	JsonWriter(os).value(1700000000.123456);
	EXPECT_EQ(os.str(), "1700000000.12346");
}

TEST(SvgPanel, MapsDataToPixelsWithEqualAspect)
{
	SvgPanel p(0, 0, 600, 600);
	p.setRange(0, 100, 0, 10, true);
	// Equal aspect: one metre is the same number of pixels on both axes,
	// and y grows upwards.
	const double sx = p.px(1) - p.px(0), sy = p.py(0) - p.py(1);
	EXPECT_NEAR(sx, sy, 1e-9);
	EXPECT_GT(sx, 0);
	p.polyline({{0, 0}, {50, 5}, {100, 10}}, SvgStyle{});
	p.axes("t <1>", "x", "y");
	std::ostringstream os;
	writeSvgDocument(os, 600, 600, {&p}, "doc & title");
	const std::string s = os.str();
	EXPECT_EQ(s.rfind("<?xml", 0), 0u);
	EXPECT_NE(s.find("<polyline"), std::string::npos);
	EXPECT_NE(s.find("t &lt;1&gt;"), std::string::npos);
	EXPECT_NE(s.find("doc &amp; title"), std::string::npos);
	EXPECT_NE(s.find("</svg>"), std::string::npos);
}
