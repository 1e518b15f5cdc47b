// probekit::runtime display mapping: linear radiance (the renderer's Frame::color) to the values an
// 8-bit sRGB image stores. CPU only: tools apply it to the read-back frame, so it has no GPU twin
// (ARCHITECTURE.md's rule binds GPU computations; this is none).
//
// Per pixel and channel, with exposure EV:
//     display = srgbEncode(acesFilmic(linear x 2^EV))
// acesFilmic is Krzysztof Narkowicz's fit of the ACES filmic curve (2015),
//     f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clamped to [0, 1],
// monotone, with a soft shoulder: highlights roll off instead of clipping channel by channel
// (the blocky patches of plain clamping), and it reaches 1 at x = 7.24.
//
// Automatic exposure (autoExposureEv) brings the frame's log-average luminance (Reinhard et al.,
// "Photographic Tone Reproduction for Digital Images", 2002) to middle grey 0.18:
//     EV = log2(0.18 / exp(mean over pixels of ln Y)),  Y = Rec. 709 luminance,
// over the pixels with finite Y > 0 (black background and unlit pixels do not count). A scene lit
// by a 2,049 W/m^2 sun and one lit by 1 W/m^2 get the same picture; a user's exposure offset in
// stops adds to this EV.
#pragma once

#include <span>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace probekit::runtime {

// Middle grey: what automatic exposure maps the log-average luminance to.
constexpr float kAutoExposureKey = 0.18f;

// Rec. 709 / sRGB-primaries luminance of linear RGB.
float luminance(glm::vec3 linear);

// The ACES filmic fit above; 0 for x <= 0 or NaN.
float acesFilmic(float x);

// The sRGB transfer function (IEC 61966-2-1) of a linear value clamped to [0, 1].
float srgbEncode(float linear);

// The automatic exposure of a frame (rgb of each pixel; alpha is ignored), in stops; 0 when no
// pixel has positive luminance.
float autoExposureEv(std::span<const glm::vec4> color);

// acesFilmic(linear x 2^ev) per channel: display-linear values in [0, 1] (encode with srgbEncode).
glm::vec3 toneMap(glm::vec3 linear, float ev);

} // namespace probekit::runtime
