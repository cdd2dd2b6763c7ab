// Sliced depth of field, neighbour sharing (slices.share_weights): a shared layer's pixel is split
// between the blurs of its two slice centres by τ, its splats' shares t blended as the layer is
// (u_share.r, drawn with t as a grey colour), over the layer's coverage. u_part 0: the whole
// pixel; 1: the nearer centre's part 1 − τ; 2: the farther centre's part τ.

uniform sampler2D u_share;
uniform int u_part;

float share_part(ivec2 q, float alpha) {
    if (u_part == 0) return 1.0;
    float tau = alpha > 0.0 ? clamp(texelFetch(u_share, q, 0).r / alpha, 0.0, 1.0) : 0.0;
    return u_part == 1 ? 1.0 - tau : tau;
}
