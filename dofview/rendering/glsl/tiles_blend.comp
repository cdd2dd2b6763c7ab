#version 430
// Compute rasteriser, step 5: one workgroup per listed tile (tiles_window.comp: the tiles of a
// window holding splats of a range of ranks, with their part of the tile's pairs), each thread
// blending a PIX x PIX block of pixels (one load of a splat serves PIX^2 pixels), the tile's splats
// front to back in float32 (lens.glsl: splat_alpha, the same alpha, clamp and cuts as quads.frag),
// stopping once the block's transmittance has fallen below T_MIN everywhere. Writes the Renderer
// targets: premultiplied colour and coverage, and (sum w z, sum w / z, 0, sum w), w = alpha T. With
// u_resume the targets already hold the nearer part of the scene (a depth slice or an earlier
// pass) and blending continues from them. Only the pixels of u_box are written (a depth slice's
// window: what lies beyond stays as it was, as do the tiles that hold none of its splats).
// Dispatched indirectly with tiles_window.comp's command. GROUP (threads along a side) and PIX are
// #defined.
layout(local_size_x = GROUP, local_size_y = GROUP) in;

#include "lens.glsl"
#include "splat_record.glsl"

layout(std430, binding = 0) readonly buffer Splats { Splat splats[]; };
layout(std430, binding = 1) readonly buffer TileVals { uint tile_vals[]; };
layout(std430, binding = 3) readonly buffer Order { uint order[]; };
layout(std430, binding = 5) readonly buffer Listed { uvec4 listed[]; };  // (tile x, tile y, first pair, end)
layout(std430, binding = 6) readonly buffer Command { uvec4 command; };  // w: tiles listed
layout(rgba32f, binding = 0) uniform image2D u_colour;
layout(rgba32f, binding = 1) uniform image2D u_depth;
uniform float u_tau;
uniform ivec4 u_box;  // (x0, y0, x1, y1) pixels written, GL rows, ends exclusive
uniform bool u_resume;
uniform uint u_skip;
uniform uint u_take;

const float T_MIN = 1e-4;
const float COVER_MAX = 1.0 - T_MIN;  // T ≥ T_MIN while the coverage is at most this
const uint TILE = GROUP * PIX;
const int N = int(PIX * PIX);

#include "dispatch.glsl"

void main() {
    uint index = group_index();
    if (index >= command.w) return;  // the 2D grid's last row runs past the list
    uvec4 entry = listed[index];
    uvec2 tile = entry.xy, range = entry.zw;
    // A pass blends at most u_take splats of the tile from the u_skip-th on (llvmpipe ends an
    // invocation's loops after 65535 iterations in all, so a longer tile is blended in passes).
    range.x = min(range.y, range.x + u_skip);
    range.y = range.x + min(range.y - range.x, u_take);
    // Nothing left for this pass: the tile's pixels keep what the earlier passes wrote
    if (range.x == range.y) return;
    ivec2 first = ivec2(tile * TILE + gl_LocalInvocationID.xy * PIX);
    ivec2 px[N];
    vec3 rgb[N];
    // The coverage so far, 1 − T, is accumulated as Σ αT (the transmittance T = 1 − cover): a pixel
    // with little on it keeps its coverage to float32's relative precision, as the quad backend's
    // blend does, where 1 − Π(1 − α) kept it only to 3e-8 (0.02 % of a coverage of 1.5e-4, and
    // its depth, Σ wz over the coverage, off by up to 0.5 % where little covers it).
    float cover[N], wz[N], wiz[N];
    bool live = false;  // some pixel of the block inside the image and not yet opaque
    for (int k = 0; k < N; ++k) {
        px[k] = first + ivec2(k % int(PIX), k / int(PIX));
        rgb[k] = vec3(0.0);
        cover[k] = 0.0;
        wz[k] = 0.0;
        wiz[k] = 0.0;
        bool inside = all(greaterThanEqual(px[k], u_box.xy)) && all(lessThan(px[k], u_box.zw));
        if (u_resume && inside) {
            vec4 c = imageLoad(u_colour, px[k]);
            vec4 d = imageLoad(u_depth, px[k]);
            rgb[k] = c.rgb;
            cover[k] = c.a;
            wz[k] = d.x;
            wiz[k] = d.y;
        }
        if (!inside) cover[k] = 1.0;  // never blended, never stored
        live = live || cover[k] <= COVER_MAX;
    }
    // Every thread reads the same splat at the same time (a broadcast): no shared-memory staging,
    // which on llvmpipe costs more than the loads it saves.
    for (uint j = range.x; j < range.y && live; ++j) {
        uint g = order[tile_vals[j]];
        vec4 a = splats[g].a;
        vec4 b = splats[g].b;
        vec3 colour = splats[g].c.rgb;
        vec2 axis2 = splat_axis2(a, b);
        live = false;
        for (int k = 0; k < N; ++k) {
            if (cover[k] > COVER_MAX) continue;
            float alpha = splat_alpha(vec2(px[k]) + 0.5 - a.xy, a.zw, axis2, b.z, u_tau, b.y);
            float w = alpha * (1.0 - cover[k]);
            rgb[k] += colour * w;
            wz[k] += b.w * w;
            wiz[k] += w / b.w;
            cover[k] += w;
            live = live || cover[k] <= COVER_MAX;
        }
    }
    for (int k = 0; k < N; ++k) {
        if (all(greaterThanEqual(px[k], u_box.xy)) && all(lessThan(px[k], u_box.zw))) {
            imageStore(u_colour, px[k], vec4(rgb[k], cover[k]));
            imageStore(u_depth, px[k], vec4(wz[k], wiz[k], 0.0, cover[k]));
        }
    }
}
