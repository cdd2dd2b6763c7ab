#version 430
// One instance per Gaussian, four vertices per instance (a triangle strip): project the
// Gaussian (project.glsl) and emit a quad that bounds exactly the ellipse where its alpha reaches
// tau. Culled Gaussians become a degenerate quad.
// SH_DEGREE, SH_REST (coefficients beyond degree 0, per channel) and FETCH (the storage layout's
// include file) are #defined by the loader.

layout(std430, binding = 3) readonly buffer Order { uint order[]; };      // back-to-front indices
layout(std430, binding = 4) buffer Counter { uint drawn; };

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"

uniform bool u_count;
uniform uint u_first;  // the first instance's place in the order (a depth slice's range)

// Tiles the quads may cover (tile_marks.TileMarks): one uint per tile of u_mark_size px, GL rows.
layout(std430, binding = MARKS_BINDING) buffer Marks { uint marks[]; };
uniform bool u_mark;
uniform int u_mark_size;
uniform int u_mark_columns;
uniform ivec4 u_mark_tiles;  // the box's tiles (tx0, ty0, tx1, ty1), ends exclusive: only they are marked

// The fragment measures its offset from gl_FragCoord (exact pixel centres) rather than from an
// interpolated varying, which would inherit the rasteriser's snapping of quad corners.
flat out vec2 v_centre;     // projected mean in window coordinates (y up)
flat out vec2 v_axis1;      // e1 / sqrt(l1), window coordinates: dot(d, v_axis1) is in std-devs
flat out vec2 v_axis2;
flat out float v_opacity;
flat out vec3 v_colour;
flat out float v_depth;
flat out float v_shape;     // kernel shape (lens.glsl: splat_alpha)
flat out uint v_place;      // the instance's place in the back-to-front order (deep_fragments.frag)

// Mark the tiles the quad (centre ± a1 ± a2, window coordinates, y down) may cover: on each row of
// tiles, those spanning its x-extent within the row's band, a pixel wider on every side (every
// pixel centre the rasteriser finds inside the quad lies in one of them). An elongated splat
// marks along its axis, not its bounding box.
void mark_tiles(vec2 centre, vec2 a1, vec2 a2) {
    vec2 c = vec2(centre.x, u_viewport.y - centre.y);  // GL rows
    a1.y = -a1.y;
    a2.y = -a2.y;
    vec2 half_size = abs(a1) + abs(a2) + 1.0;
    float size = float(u_mark_size);
    vec2 box_lo = vec2(u_mark_tiles.xy), box_hi = vec2(u_mark_tiles.zw) - 1.0;
    int y0 = int(clamp(floor((c.y - half_size.y) / size), box_lo.y, box_hi.y + 1.0));
    int y1 = int(clamp(floor((c.y + half_size.y) / size), box_lo.y - 1.0, box_hi.y));
    vec2 p[4] = vec2[4](c - a1 - a2, c + a1 - a2, c + a1 + a2, c - a1 + a2);
    for (int ty = y0; ty <= y1; ++ty) {
        // the quad within the band [lo, hi] of rows (a pixel wider): its x-extent over the
        // corners inside the band and the crossings of its edges with the band's two lines
        float lo = float(ty) * size - 1.0, hi = float(ty + 1) * size + 1.0;
        float xmin = 1e30, xmax = -1e30;
        for (int i = 0; i < 4; ++i) {
            vec2 a = p[i], b = p[(i + 1) & 3];
            if (a.y >= lo && a.y <= hi) {
                xmin = min(xmin, a.x);
                xmax = max(xmax, a.x);
            }
            for (int k = 0; k < 2; ++k) {
                float line = k == 0 ? lo : hi;
                if ((a.y - line) * (b.y - line) < 0.0) {
                    float x = mix(a.x, b.x, (line - a.y) / (b.y - a.y));
                    xmin = min(xmin, x);
                    xmax = max(xmax, x);
                }
            }
        }
        if (xmin > xmax) continue;
        int x0 = int(clamp(floor((xmin - 1.0) / size), box_lo.x, box_hi.x + 1.0));
        int x1 = int(clamp(floor((xmax + 1.0) / size), box_lo.x - 1.0, box_hi.x));
        for (int tx = x0; tx <= x1; ++tx) marks[ty * u_mark_columns + tx] = 1u;
    }
}

void cull() {
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // outside the clip volume: nothing rasterised
    v_centre = vec2(0.0);
    v_axis1 = vec2(0.0);
    v_axis2 = vec2(0.0);
    v_opacity = 0.0;
    v_colour = vec3(0.0);
    v_depth = 0.0;
    v_shape = 1.0;
    v_place = 0u;
}

void main() {
    Footprint f;
    v_place = u_first + uint(gl_InstanceID);
    if (!project_gaussian(order[v_place], f)) { cull(); return; }
    vec2 e1;
    float l1, l2;
    footprint_axes(f.sxx, f.sxy, f.syy, f.det, e1, l1, l2);
    vec2 e2 = vec2(-e1.y, e1.x);
    // The quad is the ellipse's bounding rectangle (r std-devs on both axes) plus half a pixel, so
    // that the rasteriser's snapping of corners never drops a pixel centre inside the ellipse.
    float r = sqrt(f.r2);
    vec2 corner = vec2((gl_VertexID & 1) == 0 ? -1.0 : 1.0, (gl_VertexID & 2) == 0 ? -1.0 : 1.0);
    vec2 px = f.centre + corner.x * (r * sqrt(l1) + 0.5) * e1 + corner.y * (r * sqrt(l2) + 0.5) * e2;

    if (u_count && gl_VertexID == 0) atomicAdd(drawn, 1u);
    if (u_mark && gl_VertexID == 0 && !any(isnan(f.centre)) && !any(isinf(f.centre)))
        mark_tiles(f.centre, (r * sqrt(l1) + 0.5) * e1, (r * sqrt(l2) + 0.5) * e2);
    gl_Position = vec4(2.0 * px.x / u_viewport.x - 1.0, 1.0 - 2.0 * px.y / u_viewport.y, 0.0, 1.0);
    vec2 flip = vec2(1.0, -1.0);
    v_centre = vec2(f.centre.x, u_viewport.y - f.centre.y);
    v_axis1 = flip * e1 * inversesqrt(l1);
    v_axis2 = flip * e2 * inversesqrt(l2);
    v_opacity = f.opacity;
    v_colour = f.colour;
    v_depth = f.depth;
    v_shape = f.shape;
}
