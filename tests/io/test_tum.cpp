#include <forest_slam/io/tum.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

using namespace forest_slam;

namespace
{
std::string tmpFile(const std::string& name, const std::string& content = "")
{
	const auto p = std::filesystem::temp_directory_path() /
				   ("fs_tum_" + std::to_string(::getpid()) + "_" + name);
	if (!content.empty()) std::ofstream(p) << content;
	return p.string();
}
std::string errorOf(const std::string& path)
{
	try
	{
		io::readTum(path);
	}
	catch (const std::runtime_error& e)
	{
		return e.what();
	}
	return "";
}
}  // namespace

TEST(Tum, RoundTrip)
{
	core::Trajectory tr(3);
	for (int i = 0; i < 3; i++)
	{
		tr[i].t_s = 1717236000.123456789 + i * 0.1;
		tr[i].pose.translation() = Eigen::Vector3d(i, -2.0 * i, 0.5);
		tr[i].pose.linear() =
			Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d(1, 2, 3).normalized())
				.toRotationMatrix();
	}
	const auto p = tmpFile("rt.tum");
	io::writeTum(p, tr);
	const auto back = io::readTum(p);
	ASSERT_EQ(back.size(), 3u);
	for (int i = 0; i < 3; i++)
	{
		EXPECT_NEAR(back[i].t_s, tr[i].t_s, 1e-6);
		EXPECT_TRUE(back[i].pose.isApprox(tr[i].pose, 1e-6));
	}
}

TEST(Tum, MalformedFilesNameFileAndLine)
{
	auto p = tmpFile("bad1.tum", "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0\n");
	auto msg = errorOf(p);
	EXPECT_NE(msg.find(p + ":3"), std::string::npos) << msg;
	p = tmpFile("bad2.tum", "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n");
	msg = errorOf(p);
	EXPECT_NE(msg.find("backwards"), std::string::npos) << msg;
	p = tmpFile("bad3.tum", "1 nan 0 0 0 0 0 1\n");
	EXPECT_NE(errorOf(p).find(":1"), std::string::npos);
	p = tmpFile("bad4.tum", "1 0 0 0 0 0 0 2\n");
	EXPECT_NE(errorOf(p).find("unit"), std::string::npos);
	EXPECT_NE(errorOf("/nonexistent.tum").find("/nonexistent.tum"), std::string::npos);
}
