// A pixel's deep samples, front to back, as its splats are walked in depth order (the rule of
// dofview/deep.py; rendering/reference.py: render_reference_deep is the numpy twin). Included by the
// two walks, deep_tiles.comp (compute backend) and deep_fragments.comp (quad backend), which call
// deep_step for each splat of the pixel and deep_finish after the last of a pass.
//
// A sample opens at a contribution of depth z0 and takes every following one up to z0 * u_reach
// (u_reach = 1 + the relative tolerance), or all of them once it is the pixel's u_cap-th. The blend
// runs as the flat image's, in its space (display-encoded for a standard sRGB scene); a sample that
// closes at the running sum E_j with transmittance T_j, opened at E_i, T_i, is stored in linear
// light as (linear(E_j) - linear(E_i)) / T_i, alpha 1 - T_j / T_i: the samples in front of any
// depth flatten to linear(E) there, all of them to the flat pixel. A walk stops at T < T_MIN (the
// compute blend's early stop). The walk of a long list runs in passes: the state is kept per pixel
// in u_state between them (u_resume: continue from it; u_last: the pass ends the list).
//
// Count mode (u_emit false): the last pass writes each pixel's number of samples into
// pixel_samples; emit mode: pixel_samples holds each pixel's first slot, and every sample is written.

struct DeepState {
    vec4 acc;    // the blend so far: premultiplied colour, transmittance
    vec4 start;  // the blend where the open sample began
    vec4 span;   // the open sample's first and farthest depth, samples closed, 1 while one is open
};

layout(std430, binding = 8) buffer State { DeepState states[]; };
layout(std430, binding = 9) buffer PixelSamples { uint pixel_samples[]; };
layout(std430, binding = 10) writeonly buffer SampleColour { vec4 sample_colour[]; };
layout(std430, binding = 11) writeonly buffer SampleDepth { vec2 sample_depth[]; };

uniform float u_reach;
uniform uint u_cap;
uniform bool u_encoded;  // the blend is display-encoded: linear = decode (tonemap.decode: a 2.2 power)
uniform bool u_emit;
uniform bool u_resume;
uniform bool u_last;

const float T_MIN = 1e-4;

DeepState deep_begin(uint p) {
    return u_resume ? states[p] : DeepState(vec4(0.0, 0.0, 0.0, 1.0), vec4(0.0, 0.0, 0.0, 1.0), vec4(0.0));
}

vec3 deep_linear(vec3 c) { return u_encoded ? pow(max(c, 0.0), vec3(2.2)) : c; }

void deep_close(inout DeepState s, uint p) {
    if (u_emit) {
        uint i = pixel_samples[p] + uint(s.span.z);
        sample_colour[i] = vec4((deep_linear(s.acc.rgb) - deep_linear(s.start.rgb)) / s.start.a,
                                1.0 - s.acc.a / s.start.a);
        sample_depth[i] = s.span.xy;
    }
    s.span.z += 1.0;
    s.span.w = 0.0;
}

// One splat of alpha (0 where it does not reach the pixel), colour (the blend's space), camera depth.
void deep_step(inout DeepState s, uint p, float alpha, vec3 colour, float depth) {
    if (!(alpha > 0.0)) return;
    if (s.span.w > 0.5 && depth > s.span.x * u_reach && uint(s.span.z) + 1u < u_cap) deep_close(s, p);
    if (s.span.w < 0.5) s = DeepState(s.acc, s.acc, vec4(depth, depth, s.span.z, 1.0));
    s.acc.rgb += colour * (alpha * s.acc.a);
    s.acc.a *= 1.0 - alpha;
    s.span.y = max(s.span.y, depth);
}

bool deep_live(DeepState s) { return s.acc.a >= T_MIN; }

void deep_finish(DeepState s, uint p) {
    if (!u_last) {
        states[p] = s;
        return;
    }
    if (s.span.w > 0.5) deep_close(s, p);
    if (!u_emit) pixel_samples[p] = uint(s.span.z);
}
