// A float32 camera depth as a uint32 key in the same order: positive floats get the sign bit set,
// negative floats are complemented (so larger magnitudes come first). -0 is made +0 first, so the
// two zeros tie and keep their index order. The same map as dofview/rendering/sort.py:depth_keys
// (which orders -0 just before +0).
uint depth_key(float z) {
    uint b = floatBitsToUint(z);
    if ((b & 0x7fffffffu) == 0u) b = 0u;
    return (b >> 31) != 0u ? ~b : (b | 0x80000000u);
}
