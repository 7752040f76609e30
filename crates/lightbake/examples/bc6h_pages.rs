//! What BC6H compression does to baked lightmap pages: each EXR page given is encoded as
//! [`lightbake::output::bc6h`] writes it and decoded again.
//!
//! ```text
//! cargo run --release -p lightbake --features internals --example bc6h_pages -- OUT/lightmaps/lightmap_0.exr ...
//! ```
//!
//! An EXR page does not say which texels are covered: the texels that are not black stand for
//! them (covered texels and the padding the bake filled). A page whose sides are not multiples
//! of 4 is extended with black texels to the next multiple. Prints per page its size, the
//! bytes as `Rgba16Float` and as BC6H, the error against the half-float page (RMS relative to
//! the RMS texel, 99th percentile and worst texel), the blocks holding two islands of texels,
//! and the encoding time.

use glam::Vec3;
use lightbake::lightmap::LightmapPage;
use lightbake::output::bc6h;

fn main() {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: bc6h_pages PAGE.exr ...");
        std::process::exit(2);
    }
    println!(
        "| page | texels | Rgba16Float | BC6H | RMS | p99 | worst | blocks with two islands | encode |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|");
    for path in paths {
        let img = match image::open(&path) {
            Ok(i) => i.into_rgb32f(),
            Err(e) => {
                eprintln!("{path}: {e}");
                std::process::exit(1);
            }
        };
        let (w, h) = img.dimensions();
        let (pw, ph) = (w.next_multiple_of(4), h.next_multiple_of(4));
        let mut page = LightmapPage::black(pw, ph);
        for (x, y, p) in img.enumerate_pixels() {
            let v = Vec3::new(p[0], p[1], p[2]);
            let i = (y * pw + x) as usize;
            page.texels[i] = v;
            page.covered[i] = v.max_element() > 0.0;
        }
        let start = std::time::Instant::now();
        let bytes = bc6h::encode_ktx2_bc6h(&page).expect("encode");
        let secs = start.elapsed().as_secs_f64();
        let e = bc6h::measure(&page, &bytes).expect("measure");
        println!(
            "| {path} | {w}×{h} | {:.2} MiB | {:.2} MiB | {:.3}% | {:.2}% | {:.1}% | {} of {} | {secs:.2} s |",
            (u64::from(w) * u64::from(h) * 8) as f64 / 1048576.0,
            bytes.len() as f64 / 1048576.0,
            100.0 * e.rms_relative,
            100.0 * e.p99_relative,
            100.0 * e.worst_relative,
            e.mixed_blocks,
            e.blocks,
        );
    }
}
