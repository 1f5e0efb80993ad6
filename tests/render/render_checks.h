// tests/render/render_checks.h - what the renderer tests share beyond render_fixtures.h: views, hit errors
// against the exact CPU trace, and the checks of cone steps.
// Moved from tests/render_test.cpp; functions are inline, in the anonymous namespace the tests use.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "render/map_pack.h"
#include "render/mesh.h"
#include "render/render.h"
#include "sim/sim.h"
#include "tests/height_fields.h"

namespace {

using namespace displace;
using namespace displace::testing;
using render::Frame;
using render::HeightField;
using render::Method;
using render::MethodInfo;
using render::View;

inline View oblique_view(int pixels) {
  View view;
  view.camera.eye = {0.5f, -0.3f, 0.6f};
  view.camera.look_at = {0.5f, 0.5f, -0.05f};
  view.camera.width = pixels;
  view.camera.height = pixels;
  view.camera.fov_y_degrees = 30.0f;
  view.depth_scale = 0.1f;
  return view;
}

}  // namespace
