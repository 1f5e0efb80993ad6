// render/methods.cpp - the method table: the method names, their shader ids and what they need.
#include <algorithm>
#include <iterator>
#include <stdexcept>

#include "render/render.h"
#include "render/shaders/config.h"

namespace displace::render {
namespace {

constexpr MethodInfo methods[] = {
    {Method::bump, "bump", METHOD_BUMP, MethodFamily::surface, 0, false},
    {Method::parallax, "parallax", METHOD_PARALLAX, MethodFamily::surface, 0, false},
    {Method::parallax_limited, "parallax-limited", METHOD_PARALLAX_LIMITED, MethodFamily::surface, 0, false},
    {Method::parallax_slope, "parallax-slope", METHOD_PARALLAX_SLOPE, MethodFamily::surface, 0, false},
    {Method::pom, "pom", METHOD_POM, MethodFamily::linear_search, 0, true},
    {Method::relief, "relief", METHOD_RELIEF, MethodFamily::linear_search, 0, true},
    {Method::interval, "interval", METHOD_INTERVAL, MethodFamily::linear_search, 0, true},
    {Method::csm, "csm", METHOD_CSM, MethodFamily::cone, 1, true},
    {Method::acm4, "acm4", METHOD_ACM4, MethodFamily::cone, 4, true},
    {Method::acm8, "acm8", METHOD_ACM8, MethodFamily::cone, 8, true},
    {Method::acm4_interval, "acm4-interval", METHOD_ACM4_INTERVAL, MethodFamily::cone, 4, true},
    {Method::relaxed, "relaxed", METHOD_RELAXED, MethodFamily::cone, RELAXED_CONE_SECTORS, true, true},
    {Method::maxmip, "maxmip", METHOD_MAXMIP, MethodFamily::pyramid, 0, true},
    {Method::qdm, "qdm", METHOD_QDM, MethodFamily::pyramid, 0, true},
    {Method::sphere, "sphere", METHOD_SPHERE, MethodFamily::distance, 0, true},
    {Method::reference, "reference", METHOD_REFERENCE, MethodFamily::reference, 0, true},
};

// Methods whose search the quadrics implement (render/shaders/quadric_trace.inc.glsl). The parallax
// family offsets along the plane's tangent frame and relaxed cones hold only for straight rays in
// texture space, so those stay on the plane.
constexpr Method quadric_methods[] = {Method::bump,     Method::pom,           Method::relief,
                                      Method::interval, Method::csm,           Method::acm4,
                                      Method::acm8,     Method::acm4_interval, Method::reference};

}  // namespace

const char* surface_name(Surface surface) {
  switch (surface) {
    case Surface::plane: return "plane";
    case Surface::sphere: return "sphere";
    case Surface::cylinder: return "cylinder";
    case Surface::cone: return "cone";
    case Surface::mesh: return "mesh";
  }
  throw std::logic_error("render::Surface without a name");
}

bool supports_surface(Method method, Surface surface) {
  return surface == Surface::plane || surface == Surface::mesh ||
         std::find(std::begin(quadric_methods), std::end(quadric_methods), method) !=
             std::end(quadric_methods);
}

std::span<const MethodInfo> method_table() { return methods; }

const MethodInfo& method_info(Method method) {
  const auto found = std::find_if(std::begin(methods), std::end(methods),
                                  [&](const MethodInfo& info) { return info.method == method; });
  // every Method enumerator has a row; a missing one is a programmer error
  if (found == std::end(methods)) throw std::logic_error("render::Method without a row in the method table");
  return *found;
}

const MethodInfo* find_method(std::string_view name) {
  const auto found = std::find_if(std::begin(methods), std::end(methods),
                                  [&](const MethodInfo& info) { return name == info.name; });
  return found == std::end(methods) ? nullptr : &*found;
}

}  // namespace displace::render
