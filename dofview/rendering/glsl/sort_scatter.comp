#version 430
// Radix sort, pass step 2: move each key (and its value) to its slot, stably. Thread t owns the
// contiguous run of ITEMS keys at block * BLOCK + t * ITEMS, so a key's slot is
//   first slot of (digit, block)                      (the scanned histogram)
// + keys of that digit in the runs of threads < t     (byte counters and their prefix)
// + keys of that digit earlier in the thread's own run.
// Per (digit, thread) counts are bytes, four threads to a word (ITEMS <= 63 keeps 4 of them below
// 256, so a word's bytes can be summed by one multiply); THREADS is a multiple of 4.
layout(local_size_x = THREADS) in;
layout(std430, binding = 0) readonly buffer KeysIn { uint keys_in[]; };
layout(std430, binding = 1) readonly buffer ValsIn { uint vals_in[]; };
layout(std430, binding = 2) writeonly buffer KeysOut { uint keys_out[]; };
layout(std430, binding = 3) writeonly buffer ValsOut { uint vals_out[]; };
layout(std430, binding = 4) readonly buffer Offsets { uint offsets[]; };  // scanned histogram
uniform uint u_n;
uniform uint u_shift;
uniform uint u_blocks;

const uint WORDS = THREADS / 4u;  // counter words per digit
shared uint s_bytes[256u * WORDS];        // [digit][thread / 4], byte (thread % 4)
shared uint s_prefix[256u * WORDS / 2u];  // [digit][word]: keys of the digit before the word, 16 bits each
shared uint s_first[256];

#include "dispatch.glsl"

uint byte_sum(uint w) { return (w * 0x01010101u) >> 24; }

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint block = group_index();
    for (uint i = lid; i < 256u * WORDS; i += THREADS) s_bytes[i] = 0u;
    barrier();

    uint base = block * (THREADS * ITEMS) + lid * ITEMS;
    uint shift = 8u * (lid & 3u);
    uint word = lid >> 2;
    uint key[ITEMS];
    uint rank[ITEMS];
    for (uint j = 0u; j < ITEMS; ++j) {
        uint i = base + j;
        key[j] = i < u_n ? keys_in[i] : 0u;
        if (i < u_n) {
            uint d = (key[j] >> u_shift) & 255u;
            rank[j] = (atomicAdd(s_bytes[d * WORDS + word], 1u << shift) >> shift) & 255u;
        }
    }
    barrier();

    for (uint d = lid; d < 256u; d += THREADS) {
        uint running = 0u;
        for (uint w = 0u; w < WORDS; w += 2u) {
            uint lo = running;
            running += byte_sum(s_bytes[d * WORDS + w]);
            s_prefix[(d * WORDS + w) >> 1] = lo | (running << 16);
            running += byte_sum(s_bytes[d * WORDS + w + 1u]);
        }
        s_first[d] = offsets[d * u_blocks + block];
    }
    barrier();

    uint below = (1u << shift) - 1u;  // the bytes of the threads before this one in its word
    for (uint j = 0u; j < ITEMS; ++j) {
        uint i = base + j;
        if (i >= u_n) break;
        uint d = (key[j] >> u_shift) & 255u;
        uint slot = d * WORDS + word;
        uint prefix = (s_prefix[slot >> 1] >> (16u * (word & 1u))) & 0xffffu;
        uint pos = s_first[d] + prefix + byte_sum(s_bytes[slot] & below) + rank[j];
        keys_out[pos] = key[j];
        vals_out[pos] = vals_in[i];
    }
}
