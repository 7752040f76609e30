//! Texel patches written to bytes and read back, bit for bit: what the first process of a
//! bake split across processes (`bake prepare`) hands to the others, so that they skip the
//! rasteriser and the validity pass.

use glam::Vec3;

use super::{Patch, Patches, ValidityRays};
use crate::unwrap::Layout;

/// Magic of the file.
const MAGIC: &[u8; 8] = b"LBPATCH1";

impl Patches {
    /// The patches as bytes: every patch's fields as 21 little-endian words, the footprint
    /// lists, the page index and the validity counts.
    pub fn to_bytes(&self) -> Vec<u8> {
        let patches = self;
        let mut out = Vec::with_capacity(64 + 84 * patches.patches.len());
        let put = |w: u32, out: &mut Vec<u8>| out.extend_from_slice(&w.to_le_bytes());
        out.extend_from_slice(MAGIC);
        put(patches.patches.len() as u32, &mut out);
        for p in &patches.patches {
            for w in [p.instance, p.page, p.x, p.y] {
                put(w, &mut out);
            }
            for v in [p.position, p.normal, p.geometric_normal] {
                for c in v.to_array() {
                    put(c.to_bits(), &mut out);
                }
            }
            for w in [
                p.area.to_bits(),
                p.texel_size.to_bits(),
                p.triangle,
                p.chart,
                p.flags as u32,
                p.footprint_start,
                p.footprint_len,
                p.key,
            ] {
                put(w, &mut out);
            }
        }
        put(patches.footprint.len() as u32, &mut out);
        for &t in &patches.footprint {
            put(t, &mut out);
        }
        put(patches.page_index.len() as u32, &mut out);
        for page in &patches.page_index {
            put(page.len() as u32, &mut out);
            for &i in page {
                put(i, &mut out);
            }
        }
        for c in [
            patches.moved as u64,
            patches.rescued as u64,
            patches.invalid as u64,
            patches.visible_unlit as u64,
            patches.rays,
        ] {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out
    }

    /// [`Self::to_bytes`] read back; `None` when the bytes are not such a file.
    pub fn from_bytes(bytes: &[u8]) -> Option<Patches> {
        let mut at = 8;
        if bytes.get(..8)? != MAGIC {
            return None;
        }
        let mut word = || {
            let w = u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?);
            at += 4;
            Some(w)
        };
        let n = word()? as usize;
        // Counts are checked against the bytes that remain before anything is allocated: a
        // patch is 21 words, a footprint entry one.
        let remaining = |at: usize| bytes.len().saturating_sub(at) / 4;
        if n.checked_mul(21)? > remaining(12) {
            return None;
        }
        let mut list = Vec::with_capacity(n);
        for _ in 0..n {
            let mut w = [0u32; 20];
            for x in &mut w {
                *x = word()?;
            }
            let v = |k: usize| {
                Vec3::new(
                    f32::from_bits(w[k]),
                    f32::from_bits(w[k + 1]),
                    f32::from_bits(w[k + 2]),
                )
            };
            list.push(Patch {
                instance: w[0],
                page: w[1],
                x: w[2],
                y: w[3],
                position: v(4),
                normal: v(7),
                geometric_normal: v(10),
                area: f32::from_bits(w[13]),
                texel_size: f32::from_bits(w[14]),
                triangle: w[15],
                chart: w[16],
                flags: w[17] as u8,
                footprint_start: w[18],
                footprint_len: w[19],
                key: word()?,
            });
        }
        let footprint_len = word()? as usize;
        if footprint_len > bytes.len() / 4 {
            return None;
        }
        let footprint = (0..footprint_len)
            .map(|_| word())
            .collect::<Option<Vec<u32>>>()?;
        let pages = word()? as usize;
        if pages > bytes.len() / 4 {
            return None;
        }
        let mut page_index = Vec::with_capacity(pages);
        for _ in 0..pages {
            let len = word()? as usize;
            if len > bytes.len() / 4 {
                return None;
            }
            page_index.push((0..len).map(|_| word()).collect::<Option<Vec<u32>>>()?);
        }
        let mut counts = [0u64; 5];
        for c in &mut counts {
            *c = u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?);
            at += 8;
        }
        Some(Patches {
            patches: list,
            footprint,
            page_index,
            moved: counts[0] as usize,
            rescued: counts[1] as usize,
            invalid: counts[2] as usize,
            sealed: 0,
            visible_unlit: counts[3] as usize,
            rays: counts[4],
            ray_steps: ValidityRays::default(),
        })
    }
}

impl Patches {
    /// Checks patches read from a file against the layout and the scene they claim to be of:
    /// every index (instance, page, texel, triangle, footprint run, page entry) in range,
    /// every value finite. The file's hash covers the patches' identities, not their
    /// footprints, so this is what stands between an edited file and an out-of-range read.
    ///
    /// # Errors
    /// The first violation.
    pub fn check(&self, layout: &Layout, triangles: usize, instances: usize) -> Result<(), String> {
        if self.page_index.len() != layout.pages.len() {
            return Err(format!(
                "{} page indices for {} pages",
                self.page_index.len(),
                layout.pages.len()
            ));
        }
        for (page, (index, size)) in self.page_index.iter().zip(&layout.pages).enumerate() {
            if index.len() as u64 != size.width as u64 * size.height as u64 {
                return Err(format!("page {page}'s index does not cover its texels"));
            }
            if let Some(bad) = index
                .iter()
                .find(|&&i| i != u32::MAX && i as usize >= self.patches.len())
            {
                return Err(format!("page {page} names patch {bad}, beyond the patches"));
            }
        }
        for (i, p) in self.patches.iter().enumerate() {
            let page = layout.pages.get(p.page as usize);
            let in_page = page.is_some_and(|s| p.x < s.width && p.y < s.height);
            let footprint_end = p.footprint_start as u64 + p.footprint_len as u64;
            let ok = in_page
                && (p.instance as usize) < instances
                && (p.triangle as usize) < triangles
                && footprint_end <= self.footprint.len() as u64
                && p.position.is_finite()
                && p.normal.is_finite()
                && p.geometric_normal.is_finite()
                && p.area.is_finite()
                && p.texel_size.is_finite();
            if !ok {
                return Err(format!("patch {i} lies outside the layout or the scene"));
            }
        }
        if let Some(bad) = self.footprint.iter().find(|&&t| t as usize >= triangles) {
            return Err(format!(
                "a footprint names triangle {bad}, beyond the scene's {triangles}"
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patches_round_trip_bit_for_bit() {
        let p = Patch {
            instance: 3,
            page: 1,
            x: 7,
            y: 9,
            position: Vec3::new(1.0, -0.0, f32::MIN_POSITIVE),
            normal: Vec3::Y,
            geometric_normal: Vec3::NEG_Z,
            area: 0.25,
            texel_size: 0.5,
            triangle: 11,
            chart: 2,
            flags: Patch::VALID | Patch::MOVED,
            footprint_start: 4,
            footprint_len: 2,
            key: 0xdead_beef,
        };
        let patches = Patches {
            patches: vec![p, Patch { x: 8, ..p }],
            footprint: vec![1, 2, 3, 4, 5, 6],
            page_index: vec![vec![0, u32::MAX], vec![1]],
            moved: 2,
            rescued: 1,
            invalid: 0,
            sealed: 0,
            visible_unlit: 0,
            rays: 1 << 40,
            ray_steps: ValidityRays::default(),
        };
        let back = Patches::from_bytes(&patches.to_bytes()).unwrap();
        assert_eq!(back.patches, patches.patches);
        assert_eq!(back.footprint, patches.footprint);
        assert_eq!(back.page_index, patches.page_index);
        assert_eq!((back.moved, back.rescued, back.rays), (2, 1, 1 << 40));
        assert!(Patches::from_bytes(b"not patches").is_none());
        assert!(Patches::from_bytes(&patches.to_bytes()[..100]).is_none());
    }
}
