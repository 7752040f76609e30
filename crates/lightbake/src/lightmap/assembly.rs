//! Pages assembled from the texel patches: valid patches written, hidden ones filled from
//! their chart, the padding dilated.

use glam::Vec3;

use super::LightmapPage;
use crate::raster::Patches;
use crate::unwrap::Layout;

/// Statistics of assembling pages.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AssembleStats {
    /// Invalid texels filled from their chart neighbours.
    pub filled: usize,
    /// Invalid texels left black (their chart had no valid texel).
    pub unfilled: usize,
    /// Padding texels set by dilation.
    pub dilated: usize,
}

/// What a page texel holds while the pages are assembled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexelState {
    /// No surface: padding, set by dilation (or by a step that solves for it).
    Empty,
    /// An invalid patch (hidden), to be filled from its chart.
    Hidden,
    /// Holds its value.
    Set,
}

/// Pages being assembled: the texels and what each holds. The steps run in order:
/// [`Assembly::new`] writes the valid patches, [`Assembly::fill_hidden`] the invalid ones,
/// later steps adjust values (and may set padding texels they solve for, [`Assembly::set`]),
/// and [`Assembly::dilate`] fills the padding that is left.
#[derive(Clone, Debug)]
pub struct Assembly {
    /// The pages (E/π).
    pub pages: Vec<LightmapPage>,
    /// Per page, per texel.
    pub state: Vec<Vec<TexelState>>,
    /// Counts of the steps so far.
    pub stats: AssembleStats,
}

impl Assembly {
    /// Writes E/π of every valid patch into its page (`irradiance` per patch, lux).
    pub fn new(layout: &Layout, patches: &Patches, irradiance: &[Vec3]) -> Self {
        let mut pages: Vec<LightmapPage> = layout
            .pages
            .iter()
            .map(|p| LightmapPage::black(p.width, p.height))
            .collect();
        let mut state: Vec<Vec<TexelState>> = pages
            .iter()
            .map(|p| vec![TexelState::Empty; p.texels.len()])
            .collect();
        for (i, p) in patches.patches.iter().enumerate() {
            let page = &mut pages[p.page as usize];
            let k = (p.y * page.width + p.x) as usize;
            page.covered[k] = true;
            if p.is_valid() {
                page.texels[k] = irradiance[i] / std::f32::consts::PI;
                state[p.page as usize][k] = TexelState::Set;
            } else {
                state[p.page as usize][k] = TexelState::Hidden;
            }
        }
        Self {
            pages,
            state,
            stats: AssembleStats::default(),
        }
    }

    /// Fills the invalid texels from set neighbours of the same instance and chart, in waves;
    /// those of a chart with no valid texel stay black.
    pub fn fill_hidden(&mut self, patches: &Patches) {
        for (pi, page) in self.pages.iter_mut().enumerate() {
            let index = &patches.page_index[pi];
            let st = &mut self.state[pi];
            loop {
                let mut updates = Vec::new();
                for k in 0..st.len() {
                    if st[k] != TexelState::Hidden {
                        continue;
                    }
                    let me = &patches.patches[index[k] as usize];
                    let (sum, n) = neighbours(page.width, page.height, k, |j| {
                        if st[j] != TexelState::Set || index[j] == u32::MAX {
                            return false;
                        }
                        let other = &patches.patches[index[j] as usize];
                        other.instance == me.instance && other.chart == me.chart
                    })
                    .fold((Vec3::ZERO, 0u32), |(s, n), j| (s + page.texels[j], n + 1));
                    if n > 0 {
                        updates.push((k, sum / n as f32));
                    }
                }
                if updates.is_empty() {
                    break;
                }
                self.stats.filled += updates.len();
                for (k, v) in updates {
                    page.texels[k] = v;
                    st[k] = TexelState::Set;
                }
            }
            for s in st.iter_mut() {
                if *s == TexelState::Hidden {
                    self.stats.unfilled += 1;
                    *s = TexelState::Set; // left black, but set so dilation does not overwrite it
                }
            }
        }
    }

    /// Sets texel `k` of page `page` to `value` (a step that solves for padding texels marks
    /// them set, so dilation keeps them).
    pub fn set(&mut self, page: usize, k: usize, value: Vec3) {
        self.pages[page].texels[k] = value;
        self.state[page][k] = TexelState::Set;
    }

    /// Dilates `passes` texels into the empty space around every chart.
    pub fn dilate(&mut self, passes: u32) {
        for (page, st) in self.pages.iter_mut().zip(&mut self.state) {
            for _ in 0..passes {
                let mut updates = Vec::new();
                for k in 0..st.len() {
                    if st[k] != TexelState::Empty {
                        continue;
                    }
                    let (sum, n) =
                        neighbours(page.width, page.height, k, |j| st[j] == TexelState::Set)
                            .fold((Vec3::ZERO, 0u32), |(s, n), j| (s + page.texels[j], n + 1));
                    if n > 0 {
                        updates.push((k, sum / n as f32));
                    }
                }
                if updates.is_empty() {
                    break;
                }
                self.stats.dilated += updates.len();
                for (k, v) in updates {
                    page.texels[k] = v;
                    st[k] = TexelState::Set;
                }
            }
        }
    }
}

/// Writes E/π of every valid patch into its page, fills the invalid ones from valid
/// neighbours of the same instance and chart, then dilates `dilate_passes` texels into the
/// empty space around every chart (the steps of [`Assembly`] with nothing in between).
pub fn assemble(
    layout: &Layout,
    patches: &Patches,
    irradiance: &[Vec3],
    dilate_passes: u32,
) -> (Vec<LightmapPage>, AssembleStats) {
    let mut a = Assembly::new(layout, patches, irradiance);
    a.fill_hidden(patches);
    a.dilate(dilate_passes);
    (a.pages, a.stats)
}

/// The 8-neighbours of texel `k` accepted by `keep`.
fn neighbours(
    width: u32,
    height: u32,
    k: usize,
    keep: impl Fn(usize) -> bool,
) -> impl Iterator<Item = usize> {
    let (x, y) = ((k as u32 % width) as i64, (k as u32 / width) as i64);
    let (w, h) = (width as i64, height as i64);
    (-1i64..=1)
        .flat_map(move |dy| (-1i64..=1).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| dx != 0 || dy != 0)
        .filter_map(move |(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            (nx >= 0 && ny >= 0 && nx < w && ny < h).then_some((ny * w + nx) as usize)
        })
        .filter(move |&j| keep(j))
}
