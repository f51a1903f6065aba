// Image files read for the tests through each format's own library (libpng, libjpeg,
// OpenEXR), apart from the OpenImageIO that the server encodes and decodes with, and without
// its few hundred libraries in every test process.
#pragma once

#include <png.h>
#include <stdio.h>
// jpeglib.h needs stdio.h's FILE first.
#include <jpeglib.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace gvd::testing {

// Pixels as 8-bit values, `channels` per pixel, rows top first; the file's own channels.
struct Pixels8 {
  int width = 0, height = 0, channels = 0, file_channels = 0;
  std::vector<uint8_t> v;
};

// A PNG file's pixels as 8-bit RGB; false, with libpng's message, for bytes it cannot read.
inline bool ReadPngRgb(std::string_view bytes, Pixels8* out, std::string* error) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size())) {
    *error = image.message;
    return false;
  }
  out->file_channels = int(PNG_IMAGE_SAMPLE_CHANNELS(image.format));
  image.format = PNG_FORMAT_RGB;
  out->width = int(image.width);
  out->height = int(image.height);
  out->channels = 3;
  out->v.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out->v.data(), 0, nullptr)) {
    *error = image.message;
    return false;
  }
  return true;
}

// A JPEG file's pixels as libjpeg decodes them, in the file's own channels.
inline bool ReadJpeg(const std::string& path, Pixels8* out, std::string* error) {
  FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) {
    *error = "cannot open " + path;
    return false;
  }
  jpeg_decompress_struct info{};
  jpeg_error_mgr errors{};
  info.err = jpeg_std_error(&errors);
  jpeg_create_decompress(&info);
  jpeg_stdio_src(&info, file);
  jpeg_read_header(&info, TRUE);
  jpeg_start_decompress(&info);
  out->width = int(info.output_width);
  out->height = int(info.output_height);
  out->channels = out->file_channels = info.output_components;
  out->v.resize(size_t(out->width) * out->height * out->channels);
  while (info.output_scanline < info.output_height) {
    JSAMPROW row = &out->v[size_t(info.output_scanline) * out->width * out->channels];
    jpeg_read_scanlines(&info, &row, 1);
  }
  jpeg_finish_decompress(&info);
  jpeg_destroy_decompress(&info);
  std::fclose(file);
  return true;
}

// An OpenEXR file held in memory, for Imf::InputFile.
class ExrMemory : public Imf::IStream {
 public:
  explicit ExrMemory(std::string_view bytes) : Imf::IStream("memory"), bytes_(bytes) {}
  bool read(char c[], int n) override {
    if (at_ + size_t(n) > bytes_.size()) throw std::runtime_error("EXR file ends early");
    std::memcpy(c, bytes_.data() + at_, size_t(n));
    at_ += size_t(n);
    return at_ < bytes_.size();
  }
  uint64_t tellg() override { return at_; }
  void seekg(uint64_t at) override { at_ = at; }

 private:
  std::string_view bytes_;
  size_t at_ = 0;
};

// An OpenEXR file's one channel (named `name`) as floats, rows top first; the channels it has
// in `channels`.
inline bool ReadExrChannel(std::string_view bytes, const char* name, int* width, int* height,
                           std::vector<float>* out, std::vector<std::string>* channels,
                           std::string* error) {
  try {
    ExrMemory memory(bytes);
    Imf::InputFile file(memory);
    const Imath::Box2i window = file.header().dataWindow();
    *width = window.max.x - window.min.x + 1;
    *height = window.max.y - window.min.y + 1;
    channels->clear();
    for (auto c = file.header().channels().begin(); c != file.header().channels().end(); ++c) {
      channels->push_back(c.name());
    }
    out->assign(size_t(*width) * *height, 0.0f);
    Imf::FrameBuffer frame;
    frame.insert(name, Imf::Slice(Imf::FLOAT,
                                  reinterpret_cast<char*>(out->data() - window.min.x -
                                                          std::ptrdiff_t(window.min.y) * *width),
                                  sizeof(float), sizeof(float) * size_t(*width)));
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    return true;
  } catch (const std::exception& e) {
    *error = e.what();
    return false;
  }
}

}  // namespace gvd::testing
