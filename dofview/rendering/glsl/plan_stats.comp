#version 430
// The sliced mode's plan, step 5, one thread per ITEMS consecutive places of the slices: each
// slice's screen box (slices.screen_boxes, float32 as numpy computes it) and, for an order sorted
// for an earlier view, the depth keys of its live Gaussians in front of and behind focus
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

layout(std430, binding = 5) readonly buffer Largest { float largest[]; };  // each Gaussian's largest scale
uniform float u_gain;  // max(fx, fy)

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
        vec2 lim = 4.0 * u_viewport;
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
            float z = max(t.z, u_near);
            float tx = clamp(t.x / z, u_frustum.x, u_frustum.z), ty = clamp(t.y / z, u_frustum.y, u_frustum.w);
            float s = u_gain / z * sqrt(1.0 + tx * tx + ty * ty) * largest[g];
            float reach = 3.0 * sqrt(s * s + 0.3) + 1.0;
            vec2 uv = u_focal * t.xy / z + u_principal;
            box.xy = min(box.xy, ivec2(clamp(floor(uv - reach), -lim, lim + u_viewport)));
            box.zw = max(box.zw, ivec2(clamp(ceil(uv + reach) + 1.0, -lim, lim + u_viewport)));
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
