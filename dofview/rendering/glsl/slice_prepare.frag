#version 430
// Sliced depth of field, per reduced layer, at its level 1/u_scale: each texel made ready for the
// gather (slice_blur.glsl; at full resolution slice_visible.comp does this itself).
//
// A reduced layer's highlights leave it first (u_sprites; slices.highlights is the twin): each
// full-resolution pixel of the texel's block whose brightness stands out of the mean of the 8
// texels around it (slices.highlight_share) is appended, with its share f of the pixel's light, to
// the sprite list (slice_sprite.vert draws them), and that share is taken out of the texel with
// the weight the 2 × 2 averages gave the pixel. A layer takes all its highlights or none, so that
// which are drawn does not follow the GPU's order: they are appended as if they fit, then
// sprite_accept.comp keeps them if they fit in what is left of the frame's cap, or else draws
// none and has this pass drawn again without highlights (the layer as it was, u_sprites false).
// The layer is read through image units (cheaper than a sampler's fetches on llvmpipe).

layout(rgba32f, binding = 3) uniform readonly image2D u_colour;  // the layer at its level
layout(rgba32f, binding = 4) uniform readonly image2D u_depth;

#include "slice_blur.glsl"

uniform bool u_sprites;        // take the highlights out (a reduced layer)
layout(rgba32f, binding = 5) uniform readonly image2D u_full_colour;  // the layer at full resolution, colour
layout(rgba32f, binding = 6) uniform readonly image2D u_full_depth;   // and depth sums, its visible coverage third
uniform ivec4 u_region;        // the level's texels the layer was reduced into (x0, y0, x1, y1); beyond: empty
uniform float u_bright;        // SliceRule.bright
uniform float u_excess;        // SliceRule.excess
uniform float u_dim;           // SliceRule.dim
uniform uint u_cap;            // sprites the list holds (the frame's cap): beyond, not written

layout(std430, binding = 0) buffer Sprites {
    uint taken;       // sprites of the layers accepted so far this frame
    uint pad[3];
    vec4 sprite[];    // per sprite: colour (blend space, premultiplied), then (x, y, ρ, visible)
};
layout(std430, binding = 1) buffer Draw {  // the sprites' indirect draw: this layer's instance count
    uint vertices;
    uint instances;
    uint first;
    uint base;
};

layout(location = 0) out vec4 out_a;  // colour / N(ρ)
layout(location = 1) out vec2 out_b;  // (ρ, visible coverage / N(ρ))

// slices.brightness: the largest channel, in the blend space.
float brightness(vec4 c) {
    vec3 rgb = max(c.rgb, 0.0);
    return max(rgb.r, max(rgb.g, rgb.b));
}

// The weight of full-resolution pixel q in its texel of the level: one over the texels each 2 × 2
// average took (fewer than four where a block sticks out of the image: slices.reduce2).
float chain_weight(ivec2 q, ivec2 size) {
    float w = 1.0;
    for (int step = 1; step < u_scale; step *= 2) {
        ivec2 parent = q >> 1;
        ivec2 count = ivec2(1) + ivec2(lessThan(2 * parent + 1, size));
        w /= float(count.x * count.y);
        q = parent;
        size = (size + 1) / 2;
    }
    return w;
}

// The highlights of texel p's block appended as sprites, their light taken out of colour and depth.
void take_highlights(ivec2 p, inout vec4 colour, inout vec4 depth) {
    ivec2 size = imageSize(u_colour);
    float total = 0.0, count = 0.0;
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            ivec2 q = p + ivec2(dx, dy);
            if ((dx == 0 && dy == 0) || any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
            count += 1.0;
            if (all(greaterThanEqual(q, u_region.xy)) && all(lessThan(q, u_region.zw)))
                total += brightness(imageLoad(u_colour, q));
        }
    }
    float mean = total / max(count, 1.0);
    float kb = u_bright * mean;
    // Light is ≥ 0 (project.glsl), so no pixel of the block is brighter than s² times the texel
    // (its weight in the 2 × 2 averages is ≥ 1/s²): where that is at most what gives a share of 0
    // (≤ dim, or ≤ both B·bright and B + excess), no pixel is read at full resolution (a margin
    // for rounding). This skips the block on all but the few texels that may hold a highlight.
    float none_below = max(u_dim, kb > 0.0 ? min(kb, mean + u_excess) : 0.0);
    if (brightness(colour) * float(u_scale * u_scale) <= 0.999 * none_below) return;
    ivec2 full = imageSize(u_full_colour);
    ivec2 lo = p * u_scale, hi = min(lo + u_scale, full);
    vec4 gone = vec4(0.0), gone_depth = vec4(0.0);
    for (int y = lo.y; y < hi.y; ++y) {
        for (int x = lo.x; x < hi.x; ++x) {
            vec4 c = imageLoad(u_full_colour, ivec2(x, y));
            float lum = brightness(c);
            if (lum <= u_dim) continue;
            float ratio = kb > 0.0 ? clamp(lum / kb - 1.0, 0.0, 1.0) : 1.0;
            float excess = clamp((lum - mean) / u_excess - 1.0, 0.0, 1.0);
            float f = max(ratio, excess) * clamp(lum / u_dim - 1.0, 0.0, 1.0);
            if (f <= 0.0) continue;
            vec4 d = imageLoad(u_full_depth, ivec2(x, y));
            if (d.w <= 0.0) continue;
            uint i = atomicAdd(instances, 1u);  // all of them counted, those beyond the list not kept:
            if (i >= u_cap) continue;           // the layer is then refused (sprite_accept.comp)
            float coc = 0.5 * u_aperture * (d.y / d.w - u_inv_focus);
            float rmax = u_rmax * float(u_scale);
            sprite[2u * i] = f * c;
            sprite[2u * i + 1u] = vec4(float(x), float(y), coc < 0.0 ? -min(-coc, rmax) : min(coc, rmax), f * d.z);
            float w = chain_weight(ivec2(x, y), full) * f;
            gone += w * c;
            gone_depth += w * d;
        }
    }
    colour -= gone;
    depth -= gone_depth;
    if (depth.w <= 1e-6 * gone_depth.w) {  // all of it left (to rounding): an empty texel, as in the twin
        colour = vec4(0.0);
        depth = vec4(0.0);
    }
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 colour = imageLoad(u_colour, p);
    vec4 depth = colour.a > 0.0 ? imageLoad(u_depth, p) : vec4(0.0);
    if (u_sprites && colour.a > 0.0) take_highlights(p, colour, depth);
    prepare_texel(colour, depth, out_a, out_b);
}
