// demos/cone_export.cpp - cone-map export: lossless EXR, and Dummer's sqrt-encoded RGBA8 PNG with
// downward quantization so that 8-bit ratios stay conservative, apex heights rounded upwards for the
// same reason (layout in cone_export.h).
#include "demos/cone_export.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

namespace displace::app {
namespace {

constexpr int sectors_per_panel = 4;  // R, G, B, A

int cone_panel_count(int sector_count) { return (sector_count + sectors_per_panel - 1) / sectors_per_panel; }
// panels of a PNG cone map: the cone panels, the height panel, and for bilinear cones the apex panel
int panel_count(int sector_count, ConeKind kind) {
  return cone_panel_count(sector_count) + (kind == ConeKind::bilinear ? 2 : 1);
}

void check_export(const ConeMapExport& cones) {
  const std::size_t texels = std::size_t(cones.width) * std::size_t(cones.height);
  const std::size_t apex_size = cones.kind == ConeKind::bilinear ? texels : 0;
  if (cones.width <= 0 || cones.height <= 0 || !bake::is_valid_sector_count(cones.sector_count) ||
      cones.heights.size() != texels || cones.ratios.size() != texels * std::size_t(cones.sector_count) ||
      cones.apex.size() != apex_size ||
      !std::all_of(cones.apex.begin(), cones.apex.end(), [](float h) { return h >= 0.0f && h <= 1.0f; })) {
    throw runtime_error("internal error: inconsistent cone map export (" + std::to_string(cones.width) +
                        " x " + std::to_string(cones.height) + ", " + std::to_string(cones.sector_count) +
                        " sectors, " + cone_kind_name(cones.kind) + ")");
  }
}

Metadata cone_metadata(const ConeMapExport& cones, const Metadata& extra) {
  Metadata metadata = {
      {"displace:sectors", cones.sector_count},
      {"displace:address", std::string(address_name(cones.address))},
      {"displace:cones", std::string(cone_kind_name(cones.kind))},
      {"displace:mode", std::string(baker_name(cones.baker))},
  };
  metadata.insert(metadata.end(), extra.begin(), extra.end());
  return metadata;
}

}  // namespace

const char* cone_kind_name(ConeKind kind) { return kind == ConeKind::bilinear ? "bilinear" : "center"; }

const char* address_name(bake::Address address) { return address == bake::Address::wrap ? "wrap" : "clamp"; }

std::uint8_t encode_ratio(float ratio) {
  if (!(ratio > 0.0f)) return 0;  // also NaN: the most conservative byte
  if (ratio >= 1.0f) return 255;
  int byte = std::clamp(int(std::floor(std::sqrt(ratio) * 255.0f)), 0, 255);
  // step down until the decoded ratio is <= ratio, then up while the next byte still is
  while (byte > 0 && decode_ratio(std::uint8_t(byte)) > ratio) --byte;
  while (byte < 255 && decode_ratio(std::uint8_t(byte + 1)) <= ratio) ++byte;
  return std::uint8_t(byte);
}

float decode_ratio(std::uint8_t byte) {
  const float root = float(byte) / 255.0f;
  return root * root;
}

std::uint8_t encode_height_up(float height) {
  if (!(height > 0.0f)) return 0;
  if (height >= 1.0f) return 255;
  int byte = std::clamp(int(std::ceil(height * 255.0f)), 0, 255);
  // step up until the decoded height is >= height, then down while the byte below still is
  while (byte < 255 && decode_height(std::uint8_t(byte)) < height) ++byte;
  while (byte > 0 && decode_height(std::uint8_t(byte - 1)) >= height) --byte;
  return std::uint8_t(byte);
}

float decode_height(std::uint8_t byte) { return float(byte) / 255.0f; }

void quantize_heights_8bit(std::span<float> heights) {
  for (float& h : heights) h = std::round(std::clamp(h, 0.0f, 1.0f) * 255.0f) / 255.0f;
}

std::vector<std::uint8_t> encode_cone_png_pixels(const ConeMapExport& cones) {
  check_export(cones);
  const bool bilinear = cones.kind == ConeKind::bilinear;
  if (bilinear) {
    for (float h : cones.heights) {
      if (decode_height(encode_height_up(h)) != h) {
        throw runtime_error(
            "internal error: a bilinear cone map PNG needs heights quantized to 8 bits before baking");
      }
    }
  }
  const int panels = cone_panel_count(cones.sector_count);
  const std::size_t image_width =
      std::size_t(panel_count(cones.sector_count, cones.kind)) * std::size_t(cones.width);
  std::vector<std::uint8_t> rgba(image_width * std::size_t(cones.height) * 4, 0);
  const std::size_t n = std::size_t(cones.sector_count);

  for (std::size_t i = 0; i < std::size_t(cones.height); ++i) {
    for (std::size_t j = 0; j < std::size_t(cones.width); ++j) {
      const std::size_t texel = i * std::size_t(cones.width) + j;
      // cone panels
      for (int p = 0; p < panels; ++p) {
        std::uint8_t* pixel = &rgba[(i * image_width + std::size_t(p) * std::size_t(cones.width) + j) * 4];
        for (int c = 0; c < sectors_per_panel; ++c) {
          const std::size_t sector = std::size_t(p * sectors_per_panel + c);
          if (sector < n) {
            pixel[c] = encode_ratio(cones.ratios[texel * n + sector]);
          } else {
            pixel[c] = c == 3 ? 255 : 0;
          }
        }
      }
      // height panel
      std::uint8_t* pixel = &rgba[(i * image_width + std::size_t(panels) * std::size_t(cones.width) + j) * 4];
      pixel[0] = std::uint8_t(std::lround(std::clamp(cones.heights[texel], 0.0f, 1.0f) * 255.0f));
      pixel[1] = 0;
      pixel[2] = 0;
      pixel[3] = 255;
      // apex panel
      if (bilinear) {
        std::uint8_t* apex = pixel + std::size_t(cones.width) * 4;
        apex[0] = encode_height_up(cones.apex[texel]);
        apex[1] = 0;
        apex[2] = 0;
        apex[3] = 255;
      }
    }
  }
  return rgba;
}

void write_cone_exr(const std::filesystem::path& file, const ConeMapExport& cones, const Metadata& extra) {
  check_export(cones);
  const std::size_t texels = std::size_t(cones.width) * std::size_t(cones.height);
  const std::size_t n = std::size_t(cones.sector_count);

  // de-interleave the sectors into planes
  std::vector<std::vector<float>> planes(n, std::vector<float>(texels));
  for (std::size_t k = 0; k < texels; ++k)
    for (std::size_t s = 0; s < n; ++s) planes[s][k] = cones.ratios[k * n + s];

  std::vector<ExrChannel> channels;
  channels.push_back({"height", cones.heights});
  if (cones.kind == ConeKind::bilinear) channels.push_back({"apex", cones.apex});
  for (std::size_t s = 0; s < n; ++s) channels.push_back({"cone" + std::to_string(s), planes[s]});

  Metadata metadata = cone_metadata(cones, extra);
  metadata.push_back({"displace:height_scale", 1.0f});
  metadata.push_back({"displace:height_bias", 0.0f});
  write_exr(file, cones.width, cones.height, channels, metadata);
}

void write_cone_png(const std::filesystem::path& file, const ConeMapExport& cones, const Metadata& extra) {
  const std::vector<std::uint8_t> rgba = encode_cone_png_pixels(cones);
  write_png_rgba8(file, panel_count(cones.sector_count, cones.kind) * cones.width, cones.height, rgba,
                  cone_metadata(cones, extra));
}

DecodedConeMap decode_cone_pixels(std::span<const std::uint8_t> rgba, int image_width, int image_height,
                                  int sector_count, ConeKind kind) {
  if (!bake::is_valid_sector_count(sector_count)) {
    throw runtime_error("a cone map PNG with " + std::to_string(sector_count) + " sectors is not supported");
  }
  const int panels = cone_panel_count(sector_count);
  const int all_panels = panel_count(sector_count, kind);
  if (image_width <= 0 || image_height <= 0 || image_width % all_panels != 0 ||
      rgba.size() != std::size_t(image_width) * std::size_t(image_height) * 4) {
    throw runtime_error("a " + std::to_string(image_width) + " x " + std::to_string(image_height) +
                        " image is not a " + std::to_string(sector_count) + "-sector " +
                        cone_kind_name(kind) + " cone map PNG (expected " + std::to_string(all_panels) +
                        " panels side by side)");
  }
  DecodedConeMap decoded;
  decoded.width = image_width / all_panels;
  decoded.height = image_height;
  decoded.sector_count = sector_count;
  decoded.kind = kind;
  const std::size_t width = std::size_t(decoded.width);
  const std::size_t n = std::size_t(sector_count);
  decoded.heights.resize(width * std::size_t(image_height));
  decoded.ratios.resize(decoded.heights.size() * n);
  if (kind == ConeKind::bilinear) decoded.apex.resize(decoded.heights.size());
  for (std::size_t i = 0; i < std::size_t(image_height); ++i) {
    for (std::size_t j = 0; j < width; ++j) {
      const std::size_t texel = i * width + j;
      for (std::size_t s = 0; s < n; ++s) {
        const std::size_t panel = s / sectors_per_panel;
        const std::size_t pixel = i * std::size_t(image_width) + panel * width + j;
        decoded.ratios[texel * n + s] = decode_ratio(rgba[pixel * 4 + s % sectors_per_panel]);
      }
      const std::size_t pixel = i * std::size_t(image_width) + std::size_t(panels) * width + j;
      decoded.heights[texel] = decode_height(rgba[pixel * 4]);
      if (kind == ConeKind::bilinear) decoded.apex[texel] = decode_height(rgba[(pixel + width) * 4]);
    }
  }
  return decoded;
}

DecodedConeMap read_cone_png(const std::filesystem::path& file) {
  const Rgba8Image image = read_rgba8_image(file);
  const Attribute* sectors = find_attribute(image.metadata, "displace:sectors");
  int sector_count = 0;
  if (sectors) {
    if (const auto* number = std::get_if<int>(&sectors->value)) {
      sector_count = *number;
    } else if (const auto* text = std::get_if<std::string>(&sectors->value)) {
      sector_count = std::atoi(text->c_str());  // PNG text chunks store numbers as text
    }
  }
  if (sector_count == 0) {
    throw runtime_error("'" + file.string() +
                        "' carries no displace:sectors text chunk; it is not a cone map PNG");
  }
  ConeKind kind = ConeKind::center;
  if (const Attribute* cones = find_attribute(image.metadata, "displace:cones")) {
    const auto* text = std::get_if<std::string>(&cones->value);
    if (text && *text == "bilinear") {
      kind = ConeKind::bilinear;
    } else if (!text || *text != "center") {
      throw runtime_error("'" + file.string() + "' has an unknown displace:cones text chunk");
    }
  }
  return decode_cone_pixels(image.pixels, image.width, image.height, sector_count, kind);
}

}  // namespace displace::app
