//! Relighting a bake with light groups: when an edit changes only the colour or intensity of
//! lights (or the sky), and every member of each light group changes by the same factor per
//! colour channel, the edited bake is the weighted sum of the cached bake's group pages.
//!
//! Light adds up, and each RGB channel travels through the scene on its own (a surface
//! reflects each channel by its own albedo), so a group whose emitters all emit `w ⊙` what
//! they emitted bakes `w ⊙` its pages (the linearity a game uses to show any weighted sum of
//! the groups: [`crate::settings::groups`]). A bake with light groups keeps its groups'
//! finished pages and error estimates in the cache ([`KeptGroups`]); a later bake whose edit
//! [`relight`] can express as such weights writes their weighted sum without lighting
//! anything, and keeps the cache it followed (the weights are always relative to the pages
//! the groups were lit with, so relighting never accumulates rounding, and a light turned
//! down to black and up again is followed too).
//!
//! What it does not follow (the bake is then full, and its plan says why): geometry,
//! albedo or emissive surfaces changed; a light added, removed, moved, turned or given
//! another range, cone or baked part; a group whose members change by different factors in
//! a channel, or start to emit in a channel the group was lit without; irradiance volumes
//! (not kept) or a target error.

use glam::Vec3;

use super::BakeCache;
use super::codec::{Bad, Reader, Writer};
use super::edits::changes;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::scene::Scene;
use crate::scene::groups::resolve;
use crate::scene::hashes::SceneHashes;
use crate::settings::BakeSettings;

/// Two factors of a group's members that differ by at most this share of the larger are
/// the same factor (a colour written with a few digits, an intensity scaled in `f32`).
const SAME_FACTOR: f32 = 1e-5;

/// A lightmap page as the cache keeps it (the bake's `KeptPage`, whose module lies above
/// this one).
#[derive(Clone, Debug, PartialEq)]
pub struct KeptPage {
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
    /// E/π per texel, row-major from the top, linear RGB.
    pub texels: Vec<Vec3>,
    /// Texels that belong to a surface.
    pub covered: Vec<bool>,
}

/// One light group's finished pages and error estimate, as the bake lit it.
#[derive(Clone, Debug, PartialEq)]
pub struct KeptGroup {
    /// The group's name.
    pub name: String,
    /// Its pages (E/π, linear RGB), in the order and sizes of the bake's layout.
    pub pages: Vec<KeptPage>,
    /// Its estimated error (absolute RMS and 95th percentile, lux; none when nothing was
    /// sampled).
    pub error: Option<ErrorEstimate>,
}

/// What a bake with light groups keeps for relighting: each group's pages and estimate, and
/// the RMS luminance its estimate of the groups' sum was relative to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KeptGroups {
    /// The groups, in the bake's order (the unnamed [`crate::settings::groups::UNGROUPED`]
    /// last, when it was lit).
    pub groups: Vec<KeptGroup>,
    /// The RMS luminance of the groups' sum over the valid texel patches, lux.
    pub value_rms: f64,
}

/// The groups a relit bake writes: each group's pages and estimate weighted, their sum and
/// the estimate of the sum.
pub struct Relit {
    /// Each group's name, pages and estimate, in the cache's order.
    pub groups: Vec<KeptGroup>,
    /// The sum of the groups' pages.
    pub pages: Vec<KeptPage>,
    /// The estimate of the sum: the groups' absolute errors, each scaled with its light,
    /// added in quadrature, relative to the sum's RMS scaled alike.
    pub error: Option<ErrorEstimate>,
}

impl KeptGroups {
    pub(super) fn write(&self, w: &mut Writer) {
        w.len(self.groups.len());
        for g in &self.groups {
            w.str(&g.name);
            w.len(g.pages.len());
            for p in &g.pages {
                w.u32(p.width);
                w.u32(p.height);
                let flat: Vec<f32> = p.texels.iter().flat_map(|t| t.to_array()).collect();
                w.f32s(&flat);
                // Eight texels' coverage a byte.
                let covered: Vec<u8> = (p.covered.chunks(8))
                    .map(|c| (c.iter().enumerate()).fold(0u8, |b, (i, &v)| b | (u8::from(v) << i)))
                    .collect();
                w.bytes(&covered);
            }
            w.bool(g.error.is_some());
            if let Some(e) = &g.error {
                for v in [e.rms, e.p95_abs, e.value_rms] {
                    w.u64(v.to_bits());
                }
                w.u64(e.texels as u64);
                w.str(&e.method);
            }
        }
        w.u64(self.value_rms.to_bits());
    }

    pub(super) fn read(r: &mut Reader<'_>) -> Result<Self, Bad> {
        let n = r.len(16)?;
        let mut groups = Vec::with_capacity(n);
        for _ in 0..n {
            let name = r.str()?;
            let pages_n = r.len(16)?;
            let mut pages = Vec::with_capacity(pages_n);
            for _ in 0..pages_n {
                let (width, height) = (r.u32()?, r.u32()?);
                let flat = r.f32s()?;
                let covered = r.bytes()?;
                let texels = width as u64 * height as u64;
                if flat.len() as u64 != 3 * texels || covered.len() as u64 != texels.div_ceil(8) {
                    return Err("a light group's page does not fit its size".into());
                }
                if flat.iter().any(|v| !v.is_finite()) {
                    return Err("a light group's page holds a value that is not finite".into());
                }
                pages.push(KeptPage {
                    width,
                    height,
                    texels: flat.chunks_exact(3).map(Vec3::from_slice).collect(),
                    covered: (0..texels as usize)
                        .map(|i| covered[i / 8] >> (i % 8) & 1 != 0)
                        .collect(),
                });
            }
            let error = if r.bool()? {
                let [rms, p95_abs, value_rms] = [r.u64()?, r.u64()?, r.u64()?].map(f64::from_bits);
                let texels = r.u64()? as usize;
                let method = r.str()?;
                if ![rms, p95_abs, value_rms]
                    .iter()
                    .all(|v| v.is_finite() && *v >= 0.0)
                {
                    return Err("a light group's error estimate does not read".into());
                }
                Some(
                    ErrorEstimate {
                        rms,
                        p95_abs,
                        texels,
                        method,
                        ..ErrorEstimate::default()
                    }
                    .relative_to(value_rms),
                )
            } else {
                None
            };
            groups.push(KeptGroup { name, pages, error });
        }
        let value_rms = f64::from_bits(r.u64()?);
        if !(value_rms.is_finite() && value_rms >= 0.0) {
            return Err("the light groups' RMS value does not read".into());
        }
        Ok(Self { groups, value_rms })
    }

    /// Bytes the kept pages take in memory.
    pub fn bytes(&self) -> u64 {
        (self.groups.iter().flat_map(|g| &g.pages))
            .map(|p| p.texels.len() as u64 * 13)
            .sum()
    }

    /// The groups weighted by `weights` (one per group, per channel; see [`relight`]).
    pub fn relit(&self, weights: &[Vec3]) -> Relit {
        use rayon::prelude::*;
        let groups: Vec<KeptGroup> = (self.groups.par_iter().zip(weights))
            .map(|(g, &w)| {
                if w == Vec3::ONE {
                    return g.clone();
                }
                let pages: Vec<KeptPage> = (g.pages.iter())
                    .map(|p| KeptPage {
                        width: p.width,
                        height: p.height,
                        texels: p.texels.iter().map(|&t| t * w).collect(),
                        covered: p.covered.clone(),
                    })
                    .collect();
                let was = rms_luminance(covered(g.pages.iter()));
                let now = rms_luminance(covered(pages.iter()));
                let scale = if was > 0.0 { now / was } else { 0.0 };
                let error = g.error.as_ref().map(|e| {
                    ErrorEstimate {
                        rms: e.rms * scale,
                        p95_abs: e.p95_abs * scale,
                        ..e.clone()
                    }
                    .relative_to(e.value_rms * scale)
                });
                KeptGroup {
                    name: g.name.clone(),
                    pages,
                    error,
                }
            })
            .collect();
        let pages = sum(groups.iter().map(|g| &g.pages[..]));
        let value = if weights.iter().all(|w| *w == Vec3::ONE) {
            self.value_rms
        } else {
            let was = rms_luminance(covered(
                sum(self.groups.iter().map(|g| &g.pages[..])).iter(),
            ));
            let now = rms_luminance(covered(pages.iter()));
            if was > 0.0 {
                self.value_rms * now / was
            } else {
                0.0
            }
        };
        let errors: Vec<ErrorEstimate> = groups.iter().filter_map(|g| g.error.clone()).collect();
        let error = (!errors.is_empty()).then(|| ErrorEstimate::combine(&errors, value));
        Relit {
            groups,
            pages,
            error,
        }
    }
}

/// The covered texels of `pages`.
fn covered<'a>(pages: impl Iterator<Item = &'a KeptPage>) -> impl Iterator<Item = &'a Vec3> {
    pages.flat_map(|p| {
        p.texels
            .iter()
            .zip(&p.covered)
            .filter(|c| *c.1)
            .map(|c| c.0)
    })
}

/// The texel-wise sum of each group's pages, added in order onto black (as the bake sums
/// its groups, so that weights of 1 give its pages bit for bit).
fn sum<'a>(mut groups: impl Iterator<Item = &'a [KeptPage]>) -> Vec<KeptPage> {
    let Some(first) = groups.next() else {
        return Vec::new();
    };
    let mut out: Vec<KeptPage> = (first.iter())
        .map(|p| KeptPage {
            width: p.width,
            height: p.height,
            texels: vec![Vec3::ZERO; p.texels.len()],
            covered: p.covered.clone(),
        })
        .collect();
    for g in std::iter::once(first).chain(groups) {
        for (a, b) in out.iter_mut().zip(g) {
            for (x, y) in a.texels.iter_mut().zip(&b.texels) {
                *x += *y;
            }
        }
    }
    out
}

/// How a bake of `scene` with `settings` (which has light groups) follows `cache` by
/// relighting it: the changes in lines, and per cached group the factor per channel by which
/// its emitters' light changed.
///
/// # Errors
/// Why the edit cannot be followed by relighting (then the bake is full), in words.
pub fn relight(
    cache: &BakeCache,
    scene: &Scene,
    settings: &BakeSettings,
) -> Result<(Vec<String>, Vec<Vec3>), String> {
    let edits = changes(cache, scene, settings)?;
    const ONLY: &str = "a bake with light groups follows only changes of its lights' colour and intensity (a weighted sum of the cached group pages)";
    if settings.target_error.is_some() {
        return Err("a target error's rounds take every texel's estimate".into());
    }
    if settings.volume.enabled {
        return Err(format!("{ONLY}, and the cache keeps no irradiance volumes"));
    }
    if cache.groups.groups.is_empty() {
        return Err("the cached bake kept no light group pages".into());
    }
    if !edits.boxes.is_empty() || edits.albedo > 0 || !edits.emitters.is_empty() {
        return Err(format!(
            "{ONLY}; this edit changes geometry, albedo or emissive surfaces ({})",
            edits.lines.join("; ")
        ));
    }
    for (was, now) in &edits.lights {
        let (Some(was), Some(now)) = (was, now) else {
            return Err(format!("{ONLY}; a light was added or removed"));
        };
        let same = was.kind == now.kind
            && was.position == now.position
            && was.direction == now.direction
            && was.range == now.range
            && was.bake == now.bake
            && was.name == now.name;
        if !same {
            return Err(format!("{ONLY}; light '{}' changed otherwise", now.name));
        }
    }
    let members = resolve(scene, &settings.groups).map_err(|e| e.to_string())?;
    let kept: Vec<&str> = (cache.groups.groups.iter())
        .map(|g| g.name.as_str())
        .collect();
    let named: Vec<&str> = members.iter().map(|m| m.name.as_str()).collect();
    if named != kept {
        return Err(format!(
            "{ONLY}; the light groups are not the cached bake's ({} against {})",
            named.join(", "),
            kept.join(", ")
        ));
    }
    // Each light as the cached bake lit it, by identity.
    let hashes = SceneHashes::of(scene);
    let before = |i: usize| -> Option<Vec3> {
        let id = hashes.lights[i].0;
        let j = (cache.scene.lights.iter()).position(|(o, _)| *o == id)?;
        Some(cache.lights[j].color * cache.lights[j].intensity)
    };
    let mut weights = Vec::with_capacity(members.len());
    for m in &members {
        let name = &m.name;
        let mut pairs: Vec<(Vec3, Vec3, String)> = Vec::new();
        for &l in &m.lights {
            let now = &scene.lights[l];
            let Some(was) = before(l) else {
                return Err(format!("{ONLY}; light '{}' was added", now.name));
            };
            pairs.push((
                was,
                now.color * now.intensity,
                format!("light '{}'", now.name),
            ));
        }
        for &i in &m.materials {
            let e = scene.materials[i].emissive;
            pairs.push((e, e, format!("material '{}'", scene.materials[i].name)));
        }
        if m.sky {
            pairs.push((cache.sky, scene.sky, "the sky".into()));
        }
        weights.push(factor(&pairs).map_err(|why| format!("{ONLY}; in group {name}, {why}"))?);
    }
    Ok((edits.lines, weights))
}

/// The factor per channel that takes every `before` to its `after`.
///
/// # Errors
/// Members whose light changed by different factors in a channel, or that emit in a channel
/// in which no member of the group emitted.
fn factor(pairs: &[(Vec3, Vec3, String)]) -> Result<Vec3, String> {
    let mut w = Vec3::ONE;
    for c in 0..3 {
        let mut found: Option<(f32, &str)> = None;
        for (was, now, who) in pairs {
            let (b, a) = (was[c], now[c]);
            if b <= 0.0 {
                if a > 0.0 {
                    return Err(format!(
                        "{who} now emits in a colour channel the group was lit without"
                    ));
                }
                continue;
            }
            let r = a / b;
            match found {
                None => found = Some((r, who)),
                Some((f, first)) if (f - r).abs() > SAME_FACTOR * f.max(r) => {
                    return Err(format!(
                        "{first} and {who} changed by different factors ({f} and {r})"
                    ));
                }
                Some(_) => {}
            }
        }
        w[c] = found.map_or(1.0, |f| f.0);
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_factor_per_channel_or_the_reason_there_is_none() {
        let pair = |b: [f32; 3], a: [f32; 3]| (Vec3::from(b), Vec3::from(a), "x".to_string());
        assert_eq!(
            factor(&[pair([1.0, 2.0, 0.0], [0.5, 1.0, 0.0])]),
            Ok(Vec3::new(0.5, 0.5, 1.0))
        );
        assert_eq!(
            factor(&[
                pair([1.0, 2.0, 4.0], [3.0, 2.0, 0.0]),
                pair([2.0, 1.0, 1.0], [6.0, 1.0, 0.0])
            ]),
            Ok(Vec3::new(3.0, 1.0, 0.0))
        );
        assert!(
            factor(&[
                pair([1.0, 1.0, 1.0], [2.0, 2.0, 2.0]),
                pair([1.0; 3], [1.0; 3])
            ])
            .is_err()
        );
        assert!(factor(&[pair([1.0, 0.0, 1.0], [1.0, 0.1, 1.0])]).is_err());
    }
}
