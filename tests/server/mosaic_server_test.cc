// Mosaics (RenderMosaic) through the real gvd-server, on a synthetic image and a photograph:
// every pixel has the colour its tile's site gives it, the site nearest to the pixel's centre
// found by brute force over the sites the answer lists; bad and oversized images refused by
// name before any pixel is decoded; the image counted against --max-memory.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "gvd/client.h"
#include "tests/support/image_files.h"
#include "tests/support/metrics_scrape.h"
#include "tests/support/server_process.h"

namespace gvd {
namespace {

using grpc::StatusCode;

// 8-bit pixels, row-major from the top row.
struct Pixels {
  int w = 0, h = 0, c = 0;
  std::vector<unsigned char> v;
  const unsigned char* at(int x, int y) const { return &v[(size_t(y) * w + x) * c]; }
};

// A binary PGM or PPM (P5, P6) with 8-bit samples: this test's own reader, not the server's.
Pixels ParsePnm(const std::string& bytes) {
  std::istringstream in(bytes);
  std::string magic;
  int max = 0;
  Pixels p;
  in >> magic >> p.w >> p.h >> max;
  in.get();
  EXPECT_TRUE(magic == "P6" || magic == "P5") << magic;
  EXPECT_EQ(max, 255);
  p.c = magic == "P6" ? 3 : 1;
  p.v.resize(size_t(p.w) * p.h * p.c);
  in.read(reinterpret_cast<char*>(p.v.data()), std::streamsize(p.v.size()));
  EXPECT_TRUE(in) << "a short PNM";
  return p;
}

std::string Ppm(const Pixels& p) {
  std::ostringstream out;
  out << "P6\n" << p.w << " " << p.h << "\n255\n";
  out.write(reinterpret_cast<const char*>(p.v.data()), std::streamsize(p.v.size()));
  return out.str();
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  EXPECT_TRUE(in) << path;
  return s.str();
}

// A left half of smooth gradient and a right half of noise.
Pixels Synthetic(int w, int h, uint32_t seed) {
  Pixels p{w, h, 3, std::vector<unsigned char>(size_t(w) * h * 3)};
  std::mt19937 rng(seed);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      unsigned char* q = &p.v[(size_t(y) * w + x) * 3];
      for (int k = 0; k < 3; ++k) {
        q[k] = x < w / 2 ? static_cast<unsigned char>((x * 2 + y * k) % 256)
                         : static_cast<unsigned char>(rng() % 256);
      }
    }
  }
  return p;
}

// Per pixel, the index of the site nearest to its centre, or -1 where another site is within
// `tie` of as near (either may hold the pixel).
std::vector<int> Nearest(const v1::RenderMosaicResponse& r, double tie) {
  const int w = int(r.width_px()), h = int(r.height_px());
  std::vector<int> owner(size_t(w) * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double best = INFINITY, second = INFINITY;
      int at = -1;
      for (int s = 0; s < r.sites_size(); ++s) {
        const double d = std::hypot(r.sites(s).x() - (x + 0.5), r.sites(s).y() - (y + 0.5));
        if (d < best) {
          second = best;
          best = d;
          at = s;
        } else if (d < second) {
          second = d;
        }
      }
      owner[size_t(y) * w + x] = second - best > tie ? at : -1;
    }
  }
  return owner;
}

class MosaicServerTest : public testing::SharedServerTest {
 protected:
  static void SetUpTestSuite() { StartServer({"--max-side-px", "4096"}); }

  static v1::RenderMosaicResponse Mosaic(const std::string& image, uint32_t tiles, uint64_t seed,
                                         bool mean, bool adaptive = false) {
    v1::RenderMosaicRequest r;
    r.set_image(image);
    r.set_tiles(tiles);
    r.set_seed(seed);
    r.set_mean(mean);
    r.set_adaptive(adaptive);
    r.set_format(v1::RenderMosaicRequest::FORMAT_PNM);
    v1::RenderMosaicResponse out;
    auto s = client_->RenderMosaic(r, &out);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return out;
  }

  // Checks each pixel of the mosaic against the tile its site's colour: the input's pixel
  // under the site, or (mean) the mean of the input's pixels the oracle gives the site.
  static void ExpectTiles(const Pixels& in, const v1::RenderMosaicResponse& r, bool mean) {
    ASSERT_EQ(r.mime_type(), "image/x-portable-anymap");
    ASSERT_EQ(int(r.width_px()), in.w);
    ASSERT_EQ(int(r.height_px()), in.h);
    const Pixels out = ParsePnm(r.image());
    ASSERT_EQ(out.w, in.w);
    ASSERT_EQ(out.h, in.h);
    ASSERT_EQ(out.c, in.c);
    const std::vector<int> owner = Nearest(r, 1e-6);
    std::vector<std::vector<double>> colour(r.sites_size(), std::vector<double>(in.c, 0));
    if (mean) {
      std::vector<double> count(r.sites_size(), 0);
      for (int y = 0; y < in.h; ++y) {
        for (int x = 0; x < in.w; ++x) {
          if (int s = owner[size_t(y) * in.w + x]; s >= 0) {
            count[s] += 1;
            for (int k = 0; k < in.c; ++k) colour[s][k] += in.at(x, y)[k];
          }
        }
      }
      for (int s = 0; s < r.sites_size(); ++s) {
        for (double& v : colour[s]) v /= std::max(1.0, count[s]);
      }
    } else {
      for (int s = 0; s < r.sites_size(); ++s) {
        const auto& p = r.sites(s);
        ASSERT_TRUE(p.x() >= 0 && p.x() <= in.w && p.y() >= 0 && p.y() <= in.h) << s;
        const int x = std::min(in.w - 1, int(p.x())), y = std::min(in.h - 1, int(p.y()));
        for (int k = 0; k < in.c; ++k) colour[s][k] = in.at(x, y)[k];
      }
    }
    size_t checked = 0, wrong = 0;
    for (int y = 0; y < in.h; ++y) {
      for (int x = 0; x < in.w; ++x) {
        const int s = owner[size_t(y) * in.w + x];
        if (s < 0) continue;
        ++checked;
        for (int k = 0; k < in.c; ++k) {
          // A mean is rounded to 8 bits (or, where the oracle and the server split a tile's
          // tied pixels differently, a little off): within 1.
          if (std::abs(out.at(x, y)[k] - colour[s][k]) > (mean ? 1.0 : 0.0)) {
            if (wrong++ < 5) {
              ADD_FAILURE() << "pixel (" << x << ", " << y << ") channel " << k << " is "
                            << int(out.at(x, y)[k]) << ", its tile's (site " << s << ") "
                            << colour[s][k];
            }
          }
        }
      }
    }
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(checked, size_t(in.w) * in.h * 99 / 100) << "too many ties to check";
  }
};

TEST_F(MosaicServerTest, TilesAreTheSitesExactRegions) {
  const Pixels in = Synthetic(240, 160, 2);
  for (bool mean : {false, true}) {
    const auto r = Mosaic(Ppm(in), 300, 5, mean);
    ASSERT_EQ(r.sites_size(), 300);
    ExpectTiles(in, r, mean);
  }
  // The same seed gives the same sites; another gives others.
  const auto a = Mosaic(Ppm(in), 50, 9, false), b = Mosaic(Ppm(in), 50, 9, false),
             c = Mosaic(Ppm(in), 50, 10, false);
  EXPECT_EQ(a.SerializeAsString(), b.SerializeAsString());
  EXPECT_NE(a.sites(0).x(), c.sites(0).x());
}

// Adaptive tiles crowd where the image has detail: the noisy right half.
TEST_F(MosaicServerTest, AdaptiveTilesCrowdTheDetail) {
  const Pixels in = Synthetic(240, 160, 3);
  const auto r = Mosaic(Ppm(in), 400, 1, false, /*adaptive=*/true);
  int right = 0;
  for (const auto& p : r.sites()) right += p.x() >= 120;
  EXPECT_GT(right, 400 * 3 / 4);
  ExpectTiles(in, r, false);
}

// A photograph (JPEG): its pixels as libjpeg decodes them here.
TEST_F(MosaicServerTest, APhotograph) {
  const std::string path = std::string(GVD_GALLERY_DIR) + "/coffee.jpg";
  testing::Pixels8 decoded;
  std::string error;
  ASSERT_TRUE(testing::ReadJpeg(path, &decoded, &error)) << error;
  Pixels in{decoded.width, decoded.height, decoded.channels, decoded.v};
  const auto r = Mosaic(ReadFile(path), 1500, 1, false);
  ASSERT_EQ(r.sites_size(), 1500);
  ExpectTiles(in, r, false);
  // By default the mosaic comes back in the photograph's format.
  v1::RenderMosaicRequest jpeg;
  jpeg.set_image(ReadFile(path));
  jpeg.set_tiles(100);
  v1::RenderMosaicResponse out;
  ASSERT_TRUE(client_->RenderMosaic(jpeg, &out).ok());
  EXPECT_EQ(out.mime_type(), "image/jpeg");
  EXPECT_EQ(out.image().substr(0, 3), "\xff\xd8\xff");
}

TEST_F(MosaicServerTest, BadImagesAreRefusedByName) {
  auto expect = [](const std::string& image, uint32_t tiles, StatusCode code,
                   const std::string& words) {
    v1::RenderMosaicRequest r;
    r.set_image(image);
    r.set_tiles(tiles);
    v1::RenderMosaicResponse out;
    auto s = client_->RenderMosaic(r, &out);
    EXPECT_EQ(s.error_code(), code) << s.error_message();
    EXPECT_NE(s.error_message().find(words), std::string::npos) << s.error_message();
  };
  const std::string small = Ppm(Synthetic(20, 10, 1));
  expect("", 10, StatusCode::INVALID_ARGUMENT,
         "image is not a PNG, JPEG, WebP, GIF, BMP or PNM file (0 bytes");
  expect("<svg></svg>", 10, StatusCode::INVALID_ARGUMENT, "image is not a PNG");
  // A TIFF is an image, but not one a mosaic decodes.
  expect(std::string("II*\0", 4) + std::string(100, '\0'), 10, StatusCode::INVALID_ARGUMENT,
         "image is not a PNG");
  expect(small, 2'000'000, StatusCode::INVALID_ARGUMENT,
         "tiles is 2000000; it must be 1 to 1000000 (--max-sites-per-scene)");
  // The header is read first: a side past --max-side-px is refused with no pixel decoded.
  expect("P6\n5000 10\n255\n", 10, StatusCode::INVALID_ARGUMENT,
         "image is 5000x10 pixels; a side may be 1 to 4096 (--max-side-px)");
  expect("P6\n0 10\n255\n", 10, StatusCode::INVALID_ARGUMENT,
         "image is 0x10 pixels of 3 channels; a mosaic needs a pixel");
  // A header with too few pixels after it, a PNG cut short.
  expect(small.substr(0, small.size() - 7), 10, StatusCode::INVALID_ARGUMENT,
         "image is a damaged pnm file");
  v1::RenderMosaicRequest r;
  r.set_image(small);
  r.set_format(v1::RenderMosaicRequest::FORMAT_PNG);
  v1::RenderMosaicResponse png;
  ASSERT_TRUE(client_->RenderMosaic(r, &png).ok());
  EXPECT_EQ(png.mime_type(), "image/png");
  expect(png.image().substr(0, png.image().size() / 2), 10, StatusCode::INVALID_ARGUMENT,
         "image is a damaged png file");
  r.set_format(static_cast<v1::RenderMosaicRequest::Format>(9));
  auto s = client_->RenderMosaic(r, &png);
  EXPECT_EQ(s.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("format is 9"), std::string::npos) << s.error_message();
}

// The image counts against --max-memory while its mosaic is made, and only then.
TEST(MosaicMemoryTest, AnImagePastTheBudgetIsRefusedByName) {
  testing::ServerProcess server(GVD_SERVER_PATH,
                                {"--max-memory", "64M", "--metrics-listen", "127.0.0.1:0"});
  ASSERT_TRUE(server.error().empty()) << server.error();
  auto client = Client::Connect(server.address());
  // 2000 x 2000 RGB: 16 bytes a pixel for the image and the mosaic as floats, and more for
  // the diagram, so over 64 MiB.
  v1::RenderMosaicRequest r;
  r.set_image(Ppm(Synthetic(2000, 2000, 4)));
  r.set_tiles(100);
  v1::RenderMosaicResponse out;
  auto s = client->RenderMosaic(r, &out);
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_NE(s.error_message().find("--max-memory"), std::string::npos) << s.error_message();
  EXPECT_NE(s.error_message().find("mosaic of a 2000x2000 image"), std::string::npos)
      << s.error_message();
  r.set_image(Ppm(Synthetic(500, 500, 4)));
  s = client->RenderMosaic(r, &out);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(out.width_px(), 500u);
  // Once answered, nothing is held.
  const std::string text = testing::Scrape(testing::MetricsPort(server.log()));
  EXPECT_NE(text.find("gvd_memory_bytes 0\n"), std::string::npos) << text;
}

}  // namespace
}  // namespace gvd
