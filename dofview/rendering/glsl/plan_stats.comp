#version 430
// The sliced mode's plan, step 5, one thread per ITEMS consecutive places of the slices: each
// slice's screen box (slices.screen_boxes: the union of its Gaussians' footprints as the pinhole
// blends them, each cut to the widest guard band's rectangle u_clip, footprint.clip_boxes; float32
// where numpy computes in float64: within a pixel) and, for an order sorted for an earlier view,
// the depth keys of its live Gaussians in front of and behind focus
// (smallest, largest: the CPU turns them into the slice's smallest and largest |c| exactly, since
// |c| is monotonic in the key on either side; a sorted order has them from plan_bounds.comp). A
// thread's places lie in one slice or a few, a workgroup's in a few more: each thread reduces its
// own, the workgroup in shared memory, and a few atomics add them to the plan.
layout(local_size_x = 256) in;

#include FETCH
#include "sh.glsl"
#include "lens.glsl"
#include "project.glsl"
#include "sort_key.glsl"
#include "dispatch.glsl"
#include "plan_common.glsl"

uniform vec4 u_clip;  // the rectangle the boxes are cut to (x0, y0, x1, y1), pixels
const float CLIP_INFLATE = 1.001;  // footprint.CLIP_INFLATE

const uint ITEMS = 16u;  // places a thread
const uint SHARED = 8u;  // slices a workgroup reduces in shared memory (beyond: straight to the plan)
shared uint s_keys[SHARED * 4u];
shared int s_boxes[SHARED * 4u];
shared uint s_base;

// The slice holding place p (bounds[2 .. k + 1] are the slices' ends, ascending).
uint slice_at(uint p) {
    uint lo = 0u, hi = k;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (bounds[mid + 2u] <= p) lo = mid + 1u; else hi = mid;
    }
    return lo;
}

// (low, high) of the first coordinate over the ellipse about (p, q) of covariance
// ((sxx, sxy), (sxy, syy)), determinant det and support r2 where its second lies in [lo, hi]
// (footprint._band_extent): low > high where it never does.
vec2 band_extent(float p, float q, float sxx, float sxy, float syy, float det, float r2, float lo, float hi) {
    float ey = sqrt(r2 * syy);
    float a = max(lo, q - ey), b = min(hi, q + ey);
    if (a > b) return vec2(1.0, -1.0) * 3.0e38;
    float k = sxy / syy;
    float h = sqrt(det / syy);  // not sxx - sxy k: it cancels in float32 for a needle at the lens
    float turn = sxy * sqrt(r2 / sxx);  // y - q of the ellipse's extreme point on the high side
    float yh = clamp(q + turn, a, b) - q, yl = clamp(q - turn, a, b) - q;
    return vec2(p + k * yl - h * sqrt(max(r2 - yl * yl / syy, 0.0)),
                p + k * yh + h * sqrt(max(r2 - yh * yh / syy, 0.0)));
}

// Add one slice's reduced keys and box (identities where there were none) to the workgroup's or
// the plan's.
void add(uint v, uvec4 key, ivec4 box) {
    uint r = v - s_base;
    if (r < SHARED) {
        if (key.x <= key.y) {
            atomicMin(s_keys[r * 4u], key.x);
            atomicMax(s_keys[r * 4u + 1u], key.y);
        }
        if (key.z <= key.w) {
            atomicMin(s_keys[r * 4u + 2u], key.z);
            atomicMax(s_keys[r * 4u + 3u], key.w);
        }
        atomicMin(s_boxes[r * 4u], box.x);
        atomicMin(s_boxes[r * 4u + 1u], box.y);
        atomicMax(s_boxes[r * 4u + 2u], box.z);
        atomicMax(s_boxes[r * 4u + 3u], box.w);
        return;
    }
    if (key.x <= key.y) {
        atomicMin(keys[v * 4u], key.x);
        atomicMax(keys[v * 4u + 1u], key.y);
    }
    if (key.z <= key.w) {
        atomicMin(keys[v * 4u + 2u], key.z);
        atomicMax(keys[v * 4u + 3u], key.w);
    }
    atomicMin(boxes[v * 4u], box.x);
    atomicMin(boxes[v * 4u + 1u], box.y);
    atomicMax(boxes[v * 4u + 2u], box.z);
    atomicMax(boxes[v * 4u + 3u], box.w);
}

const uvec4 NO_KEYS = uvec4(0xffffffffu, 0u, 0xffffffffu, 0u);
const ivec4 NO_BOX = ivec4(0x7fffffff, 0x7fffffff, int(0x80000000u), int(0x80000000u));

void main() {
    uint tid = gl_LocalInvocationID.x, group = group_index() * 256u * ITEMS;
    uint lo = k > 0u ? bounds[1] : 0u, hi = k > 0u ? bounds[k + 1u] : 0u;  // the slices' places
    if (tid < SHARED * 4u) {
        s_keys[tid] = (tid & 1u) == 0u ? 0xffffffffu : 0u;
        s_boxes[tid] = (tid & 3u) < 2u ? 0x7fffffff : int(0x80000000u);
    }
    if (tid == 0u) s_base = slice_at(max(group, lo));
    barrier();
    uint p0 = max(group + tid * ITEMS, lo), p1 = min(group + (tid + 1u) * ITEMS, hi);
    if (p0 < p1) {
        uint v = slice_at(p0), end = bounds[v + 2u];
        uvec4 key = NO_KEYS;
        ivec4 box = NO_BOX;
        for (uint p = p0; p < p1; ++p) {
            if (p >= end) {
                add(v, key, box);
                key = NO_KEYS;
                box = NO_BOX;
                while (bounds[v + 2u] <= p) ++v;
                end = bounds[v + 2u];
            }
            uint g = gaussian_at(p);
            vec3 m = load_mean(g);
            if (!u_sorted) {
                uint q = depth_key(camera_depth(m));
                if (q >= u_key_near) {
                    uint side = q < u_key_focus ? 0u : 2u;
                    key[side] = min(key[side], q);
                    key[side + 1u] = max(key[side + 1u], q);
                }
            }
            vec3 t = vec3(dot(u_R0, m), dot(u_R1, m), dot(u_R2, m)) + u_T;
            vec2 c;
            vec3 cov;
            float det, r2, o, shape;
            if (!(t.z > u_near) || !footprint(g, t, c, cov, det, r2, o, shape)) continue;  // culled: draws nothing
            r2 *= CLIP_INFLATE;
            vec4 b = u_clip;  // the part of the ellipse in the rectangle: x over its rows, then y over its columns
            for (int i = 0; i < 2; ++i) {
                vec2 x = band_extent(c.x, c.y, cov.x, cov.y, cov.z, det, r2, b.y, b.w);
                b.x = max(b.x, x.x);
                b.z = min(b.z, x.y);
                vec2 y = band_extent(c.y, c.x, cov.z, cov.y, cov.x, det, r2, b.x, b.z);
                b.y = max(b.y, y.x);
                b.w = min(b.w, y.y);
            }
            if (b.x > b.z || b.y > b.w) continue;  // it misses the rectangle
            box.xy = min(box.xy, ivec2(floor(b.xy)) - 1);
            box.zw = max(box.zw, ivec2(ceil(b.zw)) + 2);
        }
        add(v, key, box);
    }
    barrier();
    if (tid < SHARED && s_base + tid < k) {
        uint v = s_base + tid;
        if (s_keys[tid * 4u] <= s_keys[tid * 4u + 1u]) {
            atomicMin(keys[v * 4u], s_keys[tid * 4u]);
            atomicMax(keys[v * 4u + 1u], s_keys[tid * 4u + 1u]);
        }
        if (s_keys[tid * 4u + 2u] <= s_keys[tid * 4u + 3u]) {
            atomicMin(keys[v * 4u + 2u], s_keys[tid * 4u + 2u]);
            atomicMax(keys[v * 4u + 3u], s_keys[tid * 4u + 3u]);
        }
        if (s_boxes[tid * 4u] <= s_boxes[tid * 4u + 2u]) {
            atomicMin(boxes[v * 4u], s_boxes[tid * 4u]);
            atomicMin(boxes[v * 4u + 1u], s_boxes[tid * 4u + 1u]);
            atomicMax(boxes[v * 4u + 2u], s_boxes[tid * 4u + 2u]);
            atomicMax(boxes[v * 4u + 3u], s_boxes[tid * 4u + 3u]);
        }
    }
}
