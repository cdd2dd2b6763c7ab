#version 430
// Scene statistics on the GPU: histograms of log2 Y (and R, G, B) of the covered pixels of the
// HDR frame, atomically counted into a small buffer that is read back (no frame read-back).
// Twin of tonemap/stats.py:log_histograms (same bins, float32).
layout(local_size_x = 16, local_size_y = 16) in;

uniform sampler2D u_colour;
uniform bool u_encoded;
uniform float u_lo;       // log2 value of bin 0's lower edge
uniform float u_scale;    // bins per stop
uniform int u_bins;
uniform int u_channels;   // 1: Y only; 4: Y, R, G, B

layout(std430, binding = 0) buffer Histogram { uint counts[]; };

const vec3 LUMINANCE = vec3(0.2126, 0.7152, 0.0722);

void count(int channel, float v) {
    int b = 0;
    if (v > 0.0) b = int(clamp(floor((log2(v) - u_lo) * u_scale), 0.0, float(u_bins - 1)));
    atomicAdd(counts[channel * u_bins + b], 1u);
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = textureSize(u_colour, 0);
    if (p.x >= size.x || p.y >= size.y) return;
    vec4 c = texelFetch(u_colour, p, 0);
    if (!(c.a > COVERED_ALPHA)) return;
    vec3 rgb = u_encoded ? pow(max(c.rgb, 0.0), vec3(2.2)) : c.rgb;
    count(0, rgb.r * LUMINANCE.r + rgb.g * LUMINANCE.g + rgb.b * LUMINANCE.b);
    if (u_channels == 4) {
        count(1, rgb.r);
        count(2, rgb.g);
        count(3, rgb.b);
    }
}
