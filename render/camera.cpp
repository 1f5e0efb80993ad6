// render/camera.cpp - the pinhole camera shared by the GPU (view-projection matrix) and the CPU
// (pixel rays for tests and the exact reference trace). Both use the same basis, so a pixel's ray on
// the CPU is the ray its fragment traces on the GPU.
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <string>

#include "render/render.h"

namespace displace::render {
namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct Basis {
  glm::dvec3 forward, right, up;
};

Basis basis(const Camera& camera) {
  const glm::dvec3 forward = glm::normalize(glm::dvec3(camera.look_at) - glm::dvec3(camera.eye));
  const glm::dvec3 right = glm::normalize(glm::cross(forward, glm::dvec3(camera.up)));
  return {forward, right, glm::cross(right, forward)};
}

}  // namespace

void Camera::validate() const {
  if (width < 1 || height < 1 || width > max_image_side || height > max_image_side) {
    throw RenderError("Camera::width and Camera::height must be between 1 and " +
                      std::to_string(max_image_side) + ", got " + std::to_string(width) + "x" +
                      std::to_string(height));
  }
  if (!finite(eye) || !finite(look_at) || !finite(up))
    throw RenderError("Camera::eye, look_at and up must be finite");
  if (!(fov_y_degrees >= min_fov_y_degrees && fov_y_degrees <= max_fov_y_degrees)) {
    char message[96];
    std::snprintf(message, sizeof message, "Camera::fov_y_degrees must be between %g and %g degrees",
                  double(min_fov_y_degrees), double(max_fov_y_degrees));
    throw RenderError(message);
  }
  const glm::dvec3 forward = glm::dvec3(look_at) - glm::dvec3(eye);
  if (glm::length(forward) < 1e-9) throw RenderError("Camera::eye and Camera::look_at must differ");
  if (glm::length(glm::cross(glm::normalize(forward), glm::dvec3(up))) < 1e-6 * glm::length(glm::dvec3(up)) ||
      glm::length(glm::dvec3(up)) < 1e-12) {
    throw RenderError("Camera::up must not be zero or parallel to the view direction");
  }
}

glm::mat4 Camera::view_projection(float near_plane, float far_plane) const {
  glm::mat4 projection =
      glm::perspective(glm::radians(fov_y_degrees), float(width) / float(height), near_plane, far_plane);
  projection[1][1] *= -1.0f;  // Vulkan's framebuffer y points down: row 0 is the top
  const Basis b = basis(*this);
  return projection * glm::lookAt(eye, eye + glm::vec3(b.forward), glm::vec3(b.up));
}

// forward + x right + y up with x = (2 px / W - 1) tan(fov / 2) aspect, y = (1 - 2 py / H) tan(fov / 2)
Camera::PixelRays Camera::pixel_rays() const {
  const Basis b = basis(*this);
  const double tan_half = std::tan(glm::radians(double(fov_y_degrees)) * 0.5);
  const double aspect = double(width) / double(height);
  return {b.forward - tan_half * aspect * b.right + tan_half * b.up,
          (2.0 * tan_half * aspect / width) * b.right, (-2.0 * tan_half / height) * b.up};
}

Ray Camera::pixel_ray(double px, double py) const {
  const PixelRays rays = pixel_rays();
  return {glm::dvec3(eye), glm::normalize(rays.corner + px * rays.along_x + py * rays.along_y)};
}

}  // namespace displace::render
