#version 430
// One direction of the bilateral operator's separable base filter (u_dir (1,0) then (0,1)):
// spatial × range (log2 L) × depth (log2 z) Gaussians × the neighbour's coverage. The first pass
// filters the guide's log2 L (bilateral_guide.frag), the second the first's output. Twin of
// tonemap/bilateral.py:Bilateral.base.

uniform sampler2D u_guide;    // log2 L, log2 z, covered, has depth
uniform sampler2D u_values;   // second pass: the first pass's output
uniform bool u_first;
uniform ivec2 u_dir;
uniform float u_sigma_px;
uniform int u_radius;
uniform float u_sigma_r;
uniform float u_sigma_z;      // 0: no depth term

out float out_value;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(u_guide, 0);
    vec4 gp = texelFetch(u_guide, p, 0);
    float vp = u_first ? gp.r : texelFetch(u_values, p, 0).r;
    float inv_s = 1.0 / (2.0 * u_sigma_px * u_sigma_px), inv_r = 1.0 / (2.0 * u_sigma_r * u_sigma_r);
    float inv_z = u_sigma_z > 0.0 ? 1.0 / (2.0 * u_sigma_z * u_sigma_z) : 0.0;
    float num = 0.0, den = 0.0;
    for (int d = -u_radius; d <= u_radius; ++d) {
        ivec2 q = p + d * u_dir;
        if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) continue;
        vec4 gq = texelFetch(u_guide, q, 0);
        if (gq.b == 0.0) continue;
        float vq = u_first ? gq.r : texelFetch(u_values, q, 0).r;
        float e = float(d * d) * inv_s + (vq - vp) * (vq - vp) * inv_r;
        if (gp.a > 0.0 && gq.a > 0.0) e += (gq.g - gp.g) * (gq.g - gp.g) * inv_z;
        float w = exp(-e);
        num += w * vq;
        den += w;
    }
    out_value = den > 0.0 ? num / den : vp;
}
