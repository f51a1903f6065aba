// The image module (codec.h): OpenImageIO's writers and readers, in memory.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "render/image/codec.h"

namespace gvd {
namespace {

absl::Status Encode(const std::string& name, const RasterView& r, std::vector<unsigned char>* bytes) {
  OIIO::Filesystem::IOVecOutput proxy(*bytes);
  auto writer = OIIO::ImageOutput::create(name, &proxy);
  if (!writer) {
    return absl::InvalidArgumentError(
        absl::StrCat("OpenImageIO has no writer for ", name, ": ", OIIO::geterror()));
  }
  const OIIO::TypeDesc type(r.type.c_str());
  OIIO::TypeDesc file = r.file_type.empty() ? type : OIIO::TypeDesc(r.file_type.c_str());
  if (file == OIIO::TypeDesc::UNKNOWN) file = OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(int(r.width), int(r.height), int(r.channels), file);
  if (!r.channel_names.empty()) spec.channelnames = r.channel_names;
  for (const auto& [key, value] : r.text_attributes) spec.attribute(key, value);
  for (const auto& [key, value] : r.float_attributes) spec.attribute(key, value);
  const auto pixel = static_cast<OIIO::stride_t>(r.pixel_bytes ? size_t(r.pixel_bytes)
                                                                : r.channels * type.size());
  if (!writer->open(name, spec) ||
      !writer->write_image(type, r.top, pixel,
                           r.row_bytes ? static_cast<OIIO::stride_t>(r.row_bytes) : pixel * r.width) ||
      !writer->close()) {
    return absl::InternalError(absl::StrCat("encoding ", name, ": ", writer->geterror()));
  }
  return absl::OkStatus();
}

absl::Status Decode(std::string_view bytes, const std::string& name,
                    const std::function<absl::Status(const RasterHeader&)>& header,
                    std::vector<float>* pixels) {
  OIIO::Filesystem::IOMemReader proxy(bytes.data(), bytes.size());
  // Created without opening, so that no other format's reader is tried on the bytes.
  auto in = OIIO::ImageInput::create(name, /*do_open=*/false, nullptr, &proxy);
  OIIO::ImageSpec spec;
  if (!in || !in->set_ioproxy(&proxy) || !in->open(name, spec)) {
    return absl::InvalidArgumentError(in ? in->geterror() : OIIO::geterror());
  }
  const RasterHeader h{static_cast<uint32_t>(std::max(0, spec.width)),
                       static_cast<uint32_t>(std::max(0, spec.height)),
                       static_cast<uint32_t>(std::max(0, spec.nchannels)), spec.format.c_str()};
  if (auto s = header(h); !s.ok()) return s;
  pixels->resize(size_t{h.width} * h.height * h.channels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels->data())) {
    return absl::InvalidArgumentError(in->geterror());
  }
  return absl::OkStatus();
}

constexpr ImageCodec kCodec{Encode, Decode};

}  // namespace
}  // namespace gvd

extern "C" __attribute__((visibility("default"))) const gvd::ImageCodec* gvd_image_codec() {
  return &gvd::kCodec;
}
