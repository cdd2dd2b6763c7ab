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
