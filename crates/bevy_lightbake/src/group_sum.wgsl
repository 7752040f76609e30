// One lightmap page shown as a weighted sum of its light groups' pages (bevy_lightbake's
// light groups): output = Σᵢ weightᵢ × groupᵢ, texel by texel. Unused slots hold a fallback
// texture with weight 0.

@group(0) @binding(0) var<uniform> weights: array<vec4<f32>, 4>;
@group(0) @binding(1) var output: texture_storage_2d<rgba16float, write>;
@group(0) @binding(2) var g0: texture_2d<f32>;
@group(0) @binding(3) var g1: texture_2d<f32>;
@group(0) @binding(4) var g2: texture_2d<f32>;
@group(0) @binding(5) var g3: texture_2d<f32>;
@group(0) @binding(6) var g4: texture_2d<f32>;
@group(0) @binding(7) var g5: texture_2d<f32>;
@group(0) @binding(8) var g6: texture_2d<f32>;
@group(0) @binding(9) var g7: texture_2d<f32>;
@group(0) @binding(10) var g8: texture_2d<f32>;
@group(0) @binding(11) var g9: texture_2d<f32>;
@group(0) @binding(12) var g10: texture_2d<f32>;
@group(0) @binding(13) var g11: texture_2d<f32>;
@group(0) @binding(14) var g12: texture_2d<f32>;
@group(0) @binding(15) var g13: texture_2d<f32>;
@group(0) @binding(16) var g14: texture_2d<f32>;
@group(0) @binding(17) var g15: texture_2d<f32>;

// Weight i times texel p of texture t, or nothing when the weight is 0 (so an unused slot's
// fallback texture, smaller than the page, is never read).
fn term(t: texture_2d<f32>, w: f32, p: vec2<i32>) -> vec3<f32> {
    if (w == 0.0) {
        return vec3<f32>(0.0);
    }
    return w * textureLoad(t, p, 0).rgb;
}

@compute @workgroup_size(8, 8, 1)
fn sum(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(output);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let p = vec2<i32>(id.xy);
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
