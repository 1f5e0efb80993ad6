// render/map_pack.cpp - maps packed into an image's layout (map_pack.h). The SSE2 path packs four
// texels at a time - a 4 x 4 transpose turns four texels' sector ratios into one vector per sector,
// encoded and joined with the apexes as they are stored - and checks the values while it copies
// them, bit for bit the scalar loop's output (MapPack.VectorisedEqualsScalar).
#include "render/map_pack.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cstdint>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace displace::render::detail {
namespace {

constexpr std::size_t parallel_pack_texels = std::size_t(1)
                                             << 16;  // rectangles at least this large pack on every core

std::size_t texel_count(const bake::Rect& rect) {
  return std::size_t(rect.x1 - rect.x0) * std::size_t(rect.y1 - rect.y0);
}

// pack_rows(first_row, end_row) over the rectangle's rows - in bands on every core when it is large -
// and whether every band's values were valid.
template <class PackRows>
bool pack_in_bands(const bake::Rect& rect, const PackRows& pack_rows) {
  if (texel_count(rect) < parallel_pack_texels) return pack_rows(rect.y0, rect.y1);
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(rect.y0, rect.y1), true,
      [&](const tbb::blocked_range<int>& rows, bool valid) {
        return pack_rows(rows.begin(), rows.end()) && valid;
      },
      [](bool a, bool b) { return a && b; });
}

}  // namespace

bool pack_heights(std::span<const float> heights, int width, const bake::Rect& rect, float* out,
                  std::size_t row_floats, bool vectorised) {
  const int columns = rect.x1 - rect.x0;
  auto pack_rows = [&](int first_row, int end_row) {
    bool valid = true;
    float* to = out + std::size_t(first_row - rect.y0) * row_floats;
    for (int y = first_row; y < end_row; ++y, to += row_floats) {
      const float* row = heights.data() + std::size_t(y) * width + rect.x0;
      int x = 0;
#if defined(__SSE2__)
      if (vectorised) {  // checked while copied: one read of the row
        __m128 ok4 = _mm_castsi128_ps(_mm_set1_epi32(-1));
        const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
        for (; x + 4 <= columns; x += 4) {
          const __m128 value = _mm_loadu_ps(row + x);
          ok4 = _mm_and_ps(ok4,
                           _mm_and_ps(_mm_cmpge_ps(value, zero), _mm_cmple_ps(value, one)));  // false for NaN
          _mm_storeu_ps(to + x, value);
        }
        valid &= _mm_movemask_ps(ok4) == 0xf;
      }
#endif
      bool ok = true;
      for (; x < columns; ++x) {
        ok &= (row[x] >= 0.0f) & (row[x] <= 1.0f);  // false for NaN
        to[x] = row[x];
      }
      valid &= ok;
    }
    return valid;
  };
  return pack_in_bands(rect, pack_rows);
}

namespace {

#if defined(__SSE2__)
// encode_ratio and encode_apex on four values, with the same operations (float min, product, sum
// and truncation round alike in SSE and in scalar code).
inline __m128i encode_ratios(__m128 ratio) {
  const __m128 clamped = _mm_min_ps(ratio, _mm_set1_ps(1.0f));
  const __m128i half =
      _mm_sub_epi32(_mm_srli_epi32(_mm_castps_si128(clamped), 13), _mm_set1_epi32((127 - 15) << 10));
  return _mm_andnot_si128(_mm_castps_si128(_mm_cmplt_ps(clamped, _mm_set1_ps(smallest_half_ratio))), half);
}
inline __m128i encode_apexes(__m128 apex) {
  const __m128 scaled = _mm_add_ps(_mm_mul_ps(apex, _mm_set1_ps(65535.0f)), _mm_set1_ps(2.0f));
  return _mm_cvttps_epi32(_mm_min_ps(scaled, _mm_set1_ps(65535.0f)));
}

// pack_cones_of's texels [x, x + 4) of a row, 4 or 8 sectors: each group of four sectors of the four
// texels transposed into one vector per sector, encoded, and joined with the encoded apexes into
// (ratio, apex) pairs - one 32-bit word per texel, R in the low half as the image stores it on this
// little-endian CPU. ok4 gathers the scalar loop's checks.
template <int sectors>
inline void pack_four_cones(const float* ratios, const float* apex, const float* relaxed, std::uint16_t* out,
                            std::size_t layer_values, __m128& ok4) {
  const __m128 apexes = _mm_loadu_ps(apex);
  const __m128i apex_high = _mm_slli_epi32(encode_apexes(apexes), 16);
  const __m128 zero = _mm_setzero_ps(), largest = _mm_set1_ps(1e30f);
  auto check = [&](__m128 value, __m128 high) {  // false for NaN
    ok4 = _mm_and_ps(ok4, _mm_and_ps(_mm_cmpge_ps(value, zero), _mm_cmple_ps(value, high)));
  };
  auto store = [&](std::uint16_t* layer, __m128 ratio) {
    _mm_storeu_si128(reinterpret_cast<__m128i*>(layer), _mm_or_si128(encode_ratios(ratio), apex_high));
  };
  check(apexes, _mm_set1_ps(1.0f));
  __m128 smallest = largest;
  for (int group = 0; group < sectors; group += 4) {
    __m128 sector0 = _mm_loadu_ps(ratios + group), sector1 = _mm_loadu_ps(ratios + sectors + group),
           sector2 = _mm_loadu_ps(ratios + 2 * sectors + group),
           sector3 = _mm_loadu_ps(ratios + 3 * sectors + group);
    _MM_TRANSPOSE4_PS(sector0, sector1, sector2, sector3);
    check(sector0, largest);
    check(sector1, largest);
    check(sector2, largest);
    check(sector3, largest);
    store(out + std::size_t(group) * layer_values, sector0);
    store(out + std::size_t(group + 1) * layer_values, sector1);
    store(out + std::size_t(group + 2) * layer_values, sector2);
    store(out + std::size_t(group + 3) * layer_values, sector3);
    smallest = _mm_min_ps(smallest, _mm_min_ps(_mm_min_ps(sector0, sector1), _mm_min_ps(sector2, sector3)));
  }
  store(out + std::size_t(sectors) * layer_values, smallest);
  if (relaxed) {
    const __m128 ratio = _mm_loadu_ps(relaxed);
    check(ratio, largest);
    store(out + std::size_t(sectors + 1) * layer_values, ratio);
  }
}
#endif

// pack_cones in one pass over the texels (the sector count a template argument, so that the loop
// unrolls).
template <int sectors>
bool pack_cones_of(const ConeMapView& cones, int width, const bake::Rect& rect, std::uint16_t* out,
                   std::size_t row_values, std::size_t layer_values, bool vectorised) {
  const bool relaxed = !cones.relaxed.empty();
  constexpr bool has_min_layer = sectors > 1;
  std::uint16_t* relaxed_out = out + layer_values * std::size_t(sectors + (has_min_layer ? 1 : 0));
  auto pack_rows = [&](int first_row, int end_row) {
    bool valid = true;
    for (int y = first_row; y < end_row; ++y) {
      const std::size_t row = std::size_t(y) * width;
      std::size_t at = std::size_t(y - rect.y0) * row_values;  // values into each layer
      int x = rect.x0;
#if defined(__SSE2__)
      if (sectors % 4 == 0 && vectorised) {
        __m128 ok4 = _mm_castsi128_ps(_mm_set1_epi32(-1));
        for (; x + 4 <= rect.x1; x += 4, at += 8) {
          const std::size_t t = row + std::size_t(x);
          pack_four_cones<sectors>(cones.ratios.data() + t * sectors, cones.apex.data() + t,
                                   relaxed ? cones.relaxed.data() + t : nullptr, out + at, layer_values, ok4);
        }
        valid &= _mm_movemask_ps(ok4) == 0xf;
      }
#endif
      for (; x < rect.x1; ++x, at += 2) {
        const std::size_t t = row + std::size_t(x);
        const float* ratios = cones.ratios.data() + t * sectors;
        const float apex = cones.apex[t];
        const std::uint16_t apex_value = encode_apex(apex);
        float smallest = ratios[0];
        bool ok = (apex >= 0.0f) & (apex <= 1.0f);
        for (int k = 0; k < sectors; ++k) {
          const float ratio = ratios[k];
          ok &= (ratio >= 0.0f) & (ratio <= 1e30f);  // false for NaN
          smallest = std::min(smallest, ratio);
          out[layer_values * std::size_t(k) + at] = encode_ratio(ratio);
          out[layer_values * std::size_t(k) + at + 1] = apex_value;
        }
        if constexpr (has_min_layer) {
          out[layer_values * sectors + at] = encode_ratio(smallest);
          out[layer_values * sectors + at + 1] = apex_value;
        }
        if (relaxed) {
          const float ratio = cones.relaxed[t];
          ok &= (ratio >= 0.0f) & (ratio <= 1e30f);
          relaxed_out[at] = encode_ratio(ratio);
          relaxed_out[at + 1] = apex_value;
        }
        valid &= ok;
      }
    }
    return valid;
  };
  return pack_in_bands(rect, pack_rows);
}

}  // namespace

bool pack_cones(const ConeMapView& cones, int width, const bake::Rect& rect, std::uint16_t* out,
                std::size_t row_values, std::size_t layer_values, bool vectorised) {
  switch (cones.sector_count) {
    case 1: return pack_cones_of<1>(cones, width, rect, out, row_values, layer_values, vectorised);
    case 4: return pack_cones_of<4>(cones, width, rect, out, row_values, layer_values, vectorised);
    default: return pack_cones_of<8>(cones, width, rect, out, row_values, layer_values, vectorised);
  }
}

}  // namespace displace::render::detail
