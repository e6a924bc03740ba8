// Target images of the applications, the orthographic views they are seen from, and the
// pictures the applications write.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "penumbra/error.hpp"
#include "penumbra/image_io.hpp"
#include "penumbra/io.hpp"
#include "penumbra/optim.hpp"

namespace penumbra::optim {
namespace {

std::string size_text(const Image& image) {
  return std::to_string(image.width) + "x" + std::to_string(image.height);
}

}  // namespace

Image load_target(const std::string& path) {
  const Image image = load_image(path);  // throws a one-line error naming the file
  if (image.width < 1 || image.height < 1 || image.channels < 1)
    throw Error("target " + path + " is empty");
  if (image.width != image.height)
    throw Error("target " + path + " is " + size_text(image) +
                "; targets must be square (the same number of pixels on both sides)");
  const int c = image.channels;
  Image mask(image.width, image.height, 1, 0.0);
  size_t shape = 0;
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
    const double* p = &image.data[i * size_t(c)];
    const double lum = c >= 3 ? 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2] : p[0];
    const double alpha = c == 2 ? p[1] : c == 4 ? p[3] : 1.0;
    const bool in = lum < 0.5 && alpha >= 0.5;
    mask.data[i] = in ? 1.0 : 0.0;
    shape += in ? 1 : 0;
  }
  if (shape == 0)
    throw Error("target " + path +
                " has no shape: every pixel is light (the shape must be dark, luminance below "
                "0.5, on a light background)");
  if (shape == mask.data.size())
    throw Error("target " + path +
                " has no background: every pixel is dark (the shape must be dark, luminance "
                "below 0.5, on a light background)");
  return mask;
}

void check_targets(const std::vector<Image>& targets, const std::vector<std::string>& names) {
  if (targets.empty()) throw Error("no target images");
  auto name = [&](size_t i) { return i < names.size() ? names[i] : "target " + std::to_string(i); };
  for (size_t i = 1; i < targets.size(); ++i)
    if (targets[i].width != targets[0].width || targets[i].height != targets[0].height)
      throw Error("targets differ in size: " + name(0) + " is " + size_text(targets[0]) + " but " +
                  name(i) + " is " + size_text(targets[i]) +
                  "; all targets must have the same size");
}

int stage_resolution(int size, int cap) {
  for (int r = std::min(size, cap); r >= 1; --r)
    if (size % r == 0) return r >= std::min(16, size) ? r : size;
  return size;
}

Image downsample(const Image& image, int factor) {
  if (factor < 1 || image.width % factor != 0 || image.height % factor != 0 || image.channels != 1)
    throw Error("downsample: " + size_text(image) + " one-channel image by " +
                std::to_string(factor) + " (the factor must divide both sides)");
  if (factor == 1) return image;
  Image out(image.width / factor, image.height / factor, 1, 0.0);
  const double inv = 1.0 / (double(factor) * factor);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) out.at(x / factor, y / factor) += image.at(x, y) * inv;
  return out;
}

Image binarize(const Image& image, double threshold) {
  Image out = image;
  for (double& v : out.data) v = v > threshold ? 1.0 : 0.0;
  return out;
}

glm::dvec3 view_up(const glm::dvec3& direction) {
  const glm::dvec3 d = glm::normalize(direction);
  return std::abs(d.y) > 0.999 ? glm::dvec3(0, 0, -1) : glm::dvec3(0, 1, 0);
}

Camera ortho_camera(const glm::dvec3& direction, double half_height, int size,
                    const glm::dvec3& center, double distance, double near, double far) {
  Camera cam;
  const glm::dvec3 d = glm::normalize(direction);
  cam.projection = Projection::Orthographic;
  cam.half_height = half_height;
  cam.eye = center - distance * d;
  cam.target = center;
  cam.up = view_up(d);
  cam.near = near;
  cam.far = far;
  cam.width = cam.height = size;
  return cam;
}

glm::dvec3 named_view(const std::string& name) {
  if (name == "front") return {0, 0, -1};
  if (name == "side") return {-1, 0, 0};
  if (name == "top") return {0, -1, 0};
  throw Error("view must be front, side or top (got '" + name + "')");
}

glm::dvec3 parse_direction(const std::string& text) {
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream in(s);
  glm::dvec3 d;
  std::string rest;
  if (!(in >> d.x >> d.y >> d.z) || (in >> rest) || !std::isfinite(d.x) || !std::isfinite(d.y) ||
      !std::isfinite(d.z))
    throw Error("a direction must be three numbers x,y,z (got '" + text + "')");
  if (!(glm::length(d) > 0)) throw Error("a direction must not be zero (got '" + text + "')");
  return glm::normalize(d);
}

Image side_by_side(const std::vector<Image>& images, int gap, double gap_value) {
  int width = 0, height = 0;
  for (const Image& im : images) {
    width += im.width;
    height = std::max(height, im.height);
  }
  if (!images.empty()) width += gap * int(images.size() - 1);
  Image out(std::max(width, 1), std::max(height, 1), 3, gap_value);
  int x0 = 0;
  for (const Image& im : images) {
    const int y0 = (height - im.height) / 2;
    for (int y = 0; y < im.height; ++y)
      for (int x = 0; x < im.width; ++x)
        for (int c = 0; c < 3; ++c)
          out.at(x0 + x, y0 + y, c) = im.at(x, y, im.channels >= 3 ? c : 0);
    x0 += im.width + gap;
  }
  return out;
}

Image upscale(const Image& image, int factor) {
  if (factor <= 1) return image;
  Image out(image.width * factor, image.height * factor, image.channels);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x)
      for (int c = 0; c < image.channels; ++c)
        out.at(x, y, c) = image.at(x / factor, y / factor, c);
  return out;
}

Image mask_picture(const Image& mask) {
  Image out(mask.width, mask.height, 3);
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x)
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = 1.0 - std::clamp(mask.at(x, y), 0.0, 1.0);
  return out;
}

}  // namespace penumbra::optim
