#version 430
// Compute rasteriser, step 1, one thread per Gaussian (of the scene, or of a span of the depth
// order: the sliced mode's layers drawn with one lens): project it (project.glsl, the same math as
// quads.vert), store the splat record and the rectangle of tiles its support box touches
// (x0 | y0 << 16, x1 | y1 << 16, ends exclusive; empty when culled). TILE (pixels) is #defined.
layout(local_size_x = 256) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "splat_record.glsl"
#include "dispatch.glsl"

layout(std430, binding = 3) writeonly buffer Splats { Splat splats[]; };
layout(std430, binding = 4) writeonly buffer Rects { uvec2 rects[]; };
layout(std430, binding = 5) buffer Counter { uint drawn; };
layout(std430, binding = 6) readonly buffer Order { uint order[]; };  // front to back
uniform bool u_ranked;  // the Gaussians of ranks [u_first, u_first + u_n) of the order, else [0, u_n)
uniform uint u_first;
uniform uint u_n;
uniform bool u_count;
uniform ivec2 u_tiles;  // tiles per row, rows

void main() {
    uint i = group_index() * 256u + gl_LocalInvocationID.x;
    if (i >= u_n) return;
    uint g = u_ranked ? order[u_first + i] : i;
    Footprint f;
    if (!project_gaussian(g, f)) {
        rects[g] = uvec2(0u);
        return;
    }
    vec2 e1;
    float l1, l2;
    footprint_axes(f.sxx, f.sxy, f.syy, f.det, e1, l1, l2);
    vec2 flip = vec2(1.0, -1.0);
    vec2 centre = vec2(f.centre.x, u_viewport.y - f.centre.y);
    splats[g] = Splat(vec4(centre, flip * e1 * inversesqrt(l1)),
                      vec4(sqrt(l1) * inversesqrt(l2), f.shape, f.opacity, f.depth), vec4(f.colour, f.r2));
    // The support's axis-aligned box, exact for the ellipse q <= r2; a tile counts when the box
    // reaches into it at all, so no pixel centre inside the ellipse is missed.
    vec2 ext = sqrt(f.r2 * vec2(f.sxx, f.syy));
    ivec2 lo = clamp(ivec2(floor((centre - ext) / float(TILE))), ivec2(0), u_tiles - 1);
    ivec2 hi = clamp(ivec2(floor((centre + ext) / float(TILE))), ivec2(0), u_tiles - 1) + 1;
    rects[g] = uvec2(uint(lo.x) | (uint(lo.y) << 16), uint(hi.x) | (uint(hi.y) << 16));
    if (u_count) atomicAdd(drawn, 1u);
}
