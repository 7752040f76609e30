// One lightmap page (or one irradiance volume's 3D voxel image) shown as a weighted sum of its
// light groups' images (bevy_lightbake's light groups): output = Σᵢ weightᵢ × groupᵢ, texel
// by texel. Unused slots hold a fallback texture with weight 0.
//
// The plugin (`groups::sum_shader`) puts in front of this, for pages or volumes: the alias
// `Group` (the sources' texture type), the alias `Texel` (a texel's coordinates), the
// storage texture `output` at binding 1, and `texel_of(id) -> At`, the texel `p` of
// invocation `id` and whether it is `inside` the output. Bevy 0.20 passes WGSL shaders to
// the GPU as they are (no `#ifdef`).

@group(0) @binding(0) var<uniform> weights: array<vec4<f32>, 4>;
@group(0) @binding(2) var g0: Group;
@group(0) @binding(3) var g1: Group;
@group(0) @binding(4) var g2: Group;
@group(0) @binding(5) var g3: Group;
@group(0) @binding(6) var g4: Group;
@group(0) @binding(7) var g5: Group;
@group(0) @binding(8) var g6: Group;
@group(0) @binding(9) var g7: Group;
@group(0) @binding(10) var g8: Group;
@group(0) @binding(11) var g9: Group;
@group(0) @binding(12) var g10: Group;
@group(0) @binding(13) var g11: Group;
@group(0) @binding(14) var g12: Group;
@group(0) @binding(15) var g13: Group;
@group(0) @binding(16) var g14: Group;
@group(0) @binding(17) var g15: Group;

// Weight i times texel p of texture t, or nothing when the weight is 0 (so an unused slot's
// fallback texture, smaller than the page, is never read).
fn term(t: Group, w: f32, p: Texel) -> vec3<f32> {
    if (w == 0.0) {
        return vec3<f32>(0.0);
    }
    return w * textureLoad(t, p, 0).rgb;
}

@compute @workgroup_size(8, 8, 1)
fn sum(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = texel_of(id);
    if (!t.inside) {
        return;
    }
    let p = t.p;
    var s = term(g0, weights[0].x, p);
    s += term(g1, weights[0].y, p);
    s += term(g2, weights[0].z, p);
    s += term(g3, weights[0].w, p);
    s += term(g4, weights[1].x, p);
    s += term(g5, weights[1].y, p);
    s += term(g6, weights[1].z, p);
    s += term(g7, weights[1].w, p);
    s += term(g8, weights[2].x, p);
    s += term(g9, weights[2].y, p);
    s += term(g10, weights[2].z, p);
    s += term(g11, weights[2].w, p);
    s += term(g12, weights[3].x, p);
    s += term(g13, weights[3].y, p);
    s += term(g14, weights[3].z, p);
    s += term(g15, weights[3].w, p);
    textureStore(output, p, vec4<f32>(s, 1.0));
}
