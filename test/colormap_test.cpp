// Colour maps and ranges.
#include <lapmesh/colormap.h>

#include <gtest/gtest.h>

#include <set>

TEST(Colormap, EndpointsAndMidpoints)
{
  using lapmesh::Colormap;
  const auto jet0 = lapmesh::map_color(Colormap::jet, 0.0), jet1 = lapmesh::map_color(Colormap::jet, 1.0);
  EXPECT_EQ(jet0.b, 128); EXPECT_EQ(jet0.r, 0);   // dark blue
  EXPECT_EQ(jet1.r, 128); EXPECT_EQ(jet1.b, 0);   // dark red
  const auto jet_mid = lapmesh::map_color(Colormap::jet, 0.5);
  EXPECT_EQ(jet_mid.g, 255);
  const auto v0 = lapmesh::map_color(Colormap::viridis, 0.0), v1 = lapmesh::map_color(Colormap::viridis, 1.0);
  EXPECT_EQ(v0.r, 68); EXPECT_EQ(v0.g, 1); EXPECT_EQ(v0.b, 84);
  EXPECT_EQ(v1.r, 253); EXPECT_EQ(v1.g, 231); EXPECT_EQ(v1.b, 37);
  const auto mid = lapmesh::map_color(Colormap::coolwarm, 0.5);  // diverging: neutral grey at 0
  EXPECT_EQ(mid.r, mid.g);
  EXPECT_EQ(mid.g, mid.b);
  // clamping and NaN
  EXPECT_EQ(lapmesh::map_color(Colormap::gray, 7.0).r, 255);
  EXPECT_EQ(lapmesh::map_color(Colormap::gray, -1.0).r, 0);
  EXPECT_EQ(lapmesh::map_color(Colormap::gray, std::nan("")).r, 0);
}

TEST(Colormap, ViridisLuminanceIsMonotone)
{
  double previous = -1;
  for(int i = 0; i <= 100; ++i) {
    const auto c = lapmesh::map_color(lapmesh::Colormap::viridis, i / 100.0);
    const double y = 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
    EXPECT_GE(y, previous - 1.0) << i;  // allow one 8-bit rounding step
    previous = y;
  }
}

TEST(Colormap, AutoRangeSymmetricForSignedAndClipped)
{
  EXPECT_EQ(lapmesh::auto_range({1, 2, 3}).min, 1);
  EXPECT_EQ(lapmesh::auto_range({1, 2, 3}).max, 3);
  const auto signed_range = lapmesh::auto_range({-1, 0.5, 4});
  EXPECT_EQ(signed_range.min, -4);
  EXPECT_EQ(signed_range.max, 4);
  std::vector<double> values;
  for(int i = 0; i <= 100; ++i) values.push_back(i);
  values.push_back(1e9);  // an outlier
  values.push_back(std::nan(""));
  const auto clipped = lapmesh::auto_range(values, 1.0);
  EXPECT_EQ(clipped.min, 1);
  EXPECT_EQ(clipped.max, 100);
  const auto constant = lapmesh::auto_range({2, 2});
  EXPECT_LT(constant.min, 2);
  EXPECT_GT(constant.max, 2);
  EXPECT_THROW(lapmesh::auto_range(values, 60), std::invalid_argument);
}

TEST(Colormap, ParseRangeAndColorize)
{
  const auto r = lapmesh::parse_range("-0.5:2e1");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->min, -0.5);
  EXPECT_EQ(r->max, 20);
  for(const char* bad : {"", "1", "2:1", "1:1", "a:b", "1:2x", "nan:1", ":"}) EXPECT_FALSE(lapmesh::parse_range(bad)) << bad;
  const auto colors = lapmesh::colorize({0, 5, 10}, lapmesh::Colormap::gray, {0, 10});
  EXPECT_EQ(colors[0].r, 0);
  EXPECT_EQ(colors[1].r, 128);
  EXPECT_EQ(colors[2].r, 255);
  EXPECT_EQ(lapmesh::parse_colormap("diverging"), lapmesh::Colormap::coolwarm);
  EXPECT_FALSE(lapmesh::parse_colormap("rainbow"));
}

TEST(Colormap, SymmetricRange)
{
  // One sign only: [-max|v|, max|v|], unlike auto_range which keeps [min, max].
  const auto r = lapmesh::symmetric_range({1, 2, 3, std::nan("")});
  EXPECT_EQ(r.min, -3);
  EXPECT_EQ(r.max, 3);
  const auto neg = lapmesh::symmetric_range({-4, -1});
  EXPECT_EQ(neg.min, -4);
  EXPECT_EQ(neg.max, 4);
  // Clipping as in auto_range: 10% of 11 values drops one at each end.
  std::vector<double> v = {-100, -1, 0, 0, 0, 0, 0, 0, 0, 2, 50};
  const auto clipped = lapmesh::symmetric_range(v, 10);
  EXPECT_EQ(clipped.max, 2);
  EXPECT_EQ(clipped.min, -2);
  const auto zero = lapmesh::symmetric_range({0, 0});
  EXPECT_EQ(zero.min, -0.5);
  EXPECT_EQ(zero.max, 0.5);
  EXPECT_THROW(lapmesh::symmetric_range(v, 50), std::invalid_argument);
}

TEST(Colormap, OneTableOfNames)
{
  // Every map once, each name parsing to its map and back; the list the CLI prints.
  std::set<lapmesh::Colormap> maps;
  for(const auto& n : lapmesh::colormap_names()) {
    EXPECT_TRUE(maps.insert(n.map).second) << n.name;
    EXPECT_EQ(lapmesh::parse_colormap(n.name), n.map) << n.name;
    EXPECT_STREQ(lapmesh::to_string(n.map), n.name);
  }
  EXPECT_EQ(maps.size(), 4u);
  EXPECT_EQ(lapmesh::colormap_name_list(), "jet, viridis, coolwarm, gray");
  EXPECT_EQ(lapmesh::colormap_name_list("|"), "jet|viridis|coolwarm|gray");
  // Older spellings are still read, but they are not names of the table.
  EXPECT_EQ(lapmesh::parse_colormap("grey"), lapmesh::Colormap::gray);
  EXPECT_EQ(lapmesh::colormap_name_list().find("diverging"), std::string::npos);
}
