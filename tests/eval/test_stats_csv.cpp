#include <forest_slam/eval/csv_table.h>
#include <forest_slam/eval/position_track.h>
#include <forest_slam/eval/stats.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace forest_slam::eval;

namespace
{
std::string writeTemp(const std::string& name, const std::string& content)
{
	const auto dir = std::filesystem::temp_directory_path() /
	                 ("forest_eval_unit_" + std::to_string(::getpid()));
	std::filesystem::create_directories(dir);
	const auto p = (dir / name).string();
	std::ofstream(p) << content;
	return p;
}

std::string errorOf(const std::function<void()>& f)
{
	try
	{
		f();
	}
	catch (const std::exception& e)
	{
		return e.what();
	}
	return "";
}
}  // namespace

TEST(Stats, HandComputed)
{
	// 1,2,3,4: mean 2.5, sample std sqrt(5/3), rms sqrt(7.5), median 2.5.
	const auto s = summarize({4, 1, 3, 2});
	EXPECT_EQ(s.count, 4u);
	EXPECT_DOUBLE_EQ(s.mean, 2.5);
	EXPECT_NEAR(s.std, std::sqrt(5.0 / 3.0), 1e-12);
	EXPECT_NEAR(s.rmse, std::sqrt(7.5), 1e-12);
	EXPECT_DOUBLE_EQ(s.min, 1);
	EXPECT_DOUBLE_EQ(s.max, 4);
	EXPECT_DOUBLE_EQ(s.median, 2.5);
	EXPECT_DOUBLE_EQ(summarize({7}).std, 0.0);
	EXPECT_DOUBLE_EQ(summarize({3, 9, 1}).median, 3.0);
	EXPECT_TRUE(std::isnan(summarize({}).mean));
}

TEST(Csv, ColumnsByNameAndErrors)
{
	const auto p = writeTemp("a.csv",
	                         "# comment\n"
	                         "id, X ,y,dbh_m,extra\n"
	                         "\n"
	                         "t1,1.5,2,0.3,foo\n"
	                         "\"t2\",3,4e0,0.25,bar\n");
	const auto t = CsvTable::read(p);
	EXPECT_EQ(t.rows(), 2u);
	EXPECT_EQ(t.column("x"), 1u);
	EXPECT_EQ(t.lineOf(1), 5u);
	EXPECT_EQ(t.cell(1, 0), "t2");
	EXPECT_DOUBLE_EQ(t.number(1, t.column("y")), 4.0);
	EXPECT_FALSE(t.findColumn("z").has_value());
	EXPECT_NE(errorOf([&] { t.column("z"); })
	              .find(p + ":2: header has no column 'z'"),
	          std::string::npos);

	const auto bad = writeTemp("bad.csv", "id,x,y\n1,2,3\n2,abc,3\n");
	const auto tb = CsvTable::read(bad);
	const auto msg = errorOf([&] { tb.number(1, 1); });
	EXPECT_NE(msg.find(bad + ":3:2 (x): expected a finite number, got 'abc'"),
	          std::string::npos)
	    << msg;

	const auto ragged = writeTemp("ragged.csv", "id,x,y\n1,2,3\n2,3\n");
	EXPECT_NE(errorOf([&] { CsvTable::read(ragged); })
	              .find(ragged + ":3: expected 3"),
	          std::string::npos);
	const auto dup = writeTemp("dup.csv", "id,x,X\n");
	EXPECT_NE(errorOf([&] { CsvTable::read(dup); }).find("appears twice"),
	          std::string::npos);
	EXPECT_NE(errorOf([&] { CsvTable::read("/nonexistent/f.csv"); })
	              .find("cannot open '/nonexistent/f.csv'"),
	          std::string::npos);
	EXPECT_FALSE(parseFiniteNumber("1.5x"));
	EXPECT_FALSE(parseFiniteNumber("nan"));
	EXPECT_FALSE(parseFiniteNumber(""));
	EXPECT_DOUBLE_EQ(*parseFiniteNumber(" -2.5 "), -2.5);
}

TEST(PositionTrack, CsvAndTum)
{
	const auto csv = writeTemp("g.csv", "t,x,y,z,sats\n0,1,2,3,7\n1,4,5,6,8\n");
	const auto a = readPositionTrack(csv);
	ASSERT_EQ(a.size(), 2u);
	EXPECT_EQ(a[1].p, Eigen::Vector3d(4, 5, 6));
	const auto tum =
	    writeTemp("g.tum", "# t x y z qx qy qz qw\n0 1 2 3 0 0 0 1\n");
	const auto b = readPositionTrack(tum);
	ASSERT_EQ(b.size(), 1u);
	EXPECT_EQ(b[0].p, Eigen::Vector3d(1, 2, 3));
	const auto back = writeTemp("back.csv", "t,x,y,z\n1,0,0,0\n0.5,0,0,0\n");
	EXPECT_NE(errorOf([&] { readPositionTrack(back); })
	              .find(back + ":3:1 (t): time goes backwards"),
	          std::string::npos);
	const auto nocol = writeTemp("nocol.csv", "time,x,y,z\n1,0,0,0\n");
	EXPECT_NE(errorOf([&] { readPositionTrack(nocol); }).find("no column 't'"),
	          std::string::npos);
}
