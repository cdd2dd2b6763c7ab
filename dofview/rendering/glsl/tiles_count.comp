#version 430
// Compute rasteriser, step 2: tiles touched by each Gaussian, in depth order (counts[n] = 0, so
// that the exclusive scan of counts[0..n] ends with the total; tile_test.glsl drops the tiles of
// the support box the ellipse misses), and each workgroup's total
// (cleared by the caller), from which the CPU adds up the exact total in 64 bits: a uint32 scan
// of more than 2^32 pairs would wrap.
layout(local_size_x = 256) in;

#include "splat_record.glsl"
#include "tile_test.glsl"

layout(std430, binding = 0) readonly buffer Order { uint order[]; };
layout(std430, binding = 1) readonly buffer Rects { uvec2 rects[]; };
layout(std430, binding = 2) writeonly buffer Counts { uint counts[]; };
layout(std430, binding = 3) buffer GroupTotals { uint group_totals[]; };
layout(std430, binding = 4) readonly buffer Splats { Splat splats[]; };
uniform uint u_n;
uniform uvec2 u_span;  // the ranks tiles_preprocess.comp projected: the others count none

#include "dispatch.glsl"

void main() {
    uint group = group_index();
    uint i = group * 256u + gl_LocalInvocationID.x;
    if (i > u_n) return;
    if (i == u_n || i < u_span.x || i >= u_span.y) { counts[i] = 0u; return; }
    uvec2 r = rects[order[i]];
    uint count = ((r.y & 0xffffu) - (r.x & 0xffffu)) * ((r.y >> 16) - (r.x >> 16));
    if (count > 1u && count <= TEST_MAX) {  // the tiles the ellipse reaches (as tiles_duplicate.comp)
        Splat s = splats[order[i]];
        count = 0u;
        for (uint y = r.x >> 16; y < (r.y >> 16); ++y)
            for (uint x = r.x & 0xffffu; x < (r.y & 0xffffu); ++x)
                if (splat_touches_tile(s, uvec2(x, y))) ++count;
    }
    counts[i] = count;
    if (count > 0u) atomicAdd(group_totals[group], count);
}
