#version 430
// Sliced depth of field: one slice box-averaged down by u_scale for a blur at reduced resolution
// (slices.blur_slice's "scale"). The full image is extended by its edge pixels past its right and
// bottom borders to a multiple of u_scale, with blocks aligned at the top left as numpy's rows
// run; this target is stored with rows flipped the same way (its row 0 is the bottom block row).
// u_masked: each pixel first weighted by the pinhole transmittance in front of the slice,
// 1 − u_cover.a (the "visible" part, slices.sliced_image mode "visible"); u_part: by its share
// (slice_share.glsl).

uniform sampler2D u_src;
uniform sampler2D u_cover;
uniform int u_scale;
uniform bool u_masked;
#include "slice_share.glsl"

out vec4 out_colour;

void main() {
    ivec2 size = textureSize(u_src, 0);
    int rows = (size.y + u_scale - 1) / u_scale;
    ivec2 p = ivec2(gl_FragCoord.xy);
    int top = (rows - 1 - p.y) * u_scale;  // the block's first image row, counted from the top
    vec4 sum = vec4(0.0);
    for (int ky = 0; ky < u_scale; ++ky) {
        int y = max(size.y - 1 - (top + ky), 0);
        for (int kx = 0; kx < u_scale; ++kx) {
            ivec2 q = ivec2(min(p.x * u_scale + kx, size.x - 1), y);
            vec4 s = texelFetch(u_src, q, 0);
            sum += s * (u_masked ? 1.0 - texelFetch(u_cover, q, 0).a : 1.0) * share_part(q, s.a);
        }
    }
    out_colour = sum / float(u_scale * u_scale);
}
