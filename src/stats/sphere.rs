//! Histograms of directions over the unit sphere, and the expected probability mass of each
//! bin under a given solid-angle pdf (sr⁻¹); with [`super::chi2::chi2_gof`] they test a
//! direction sampler against the pdf it claims. Bins: `theta_bins` strips uniform in cos θ
//! (Archimedes' hat-box theorem) times `phi_bins` sectors of φ, each of solid angle
//! 4π/(theta_bins·phi_bins) sr, plus a last invalid-direction bin of expected mass 0.
//! Layout and choices: docs/statistics.md, "`stats::sphere`".

/// Largest number of regular bins a binning may have; larger (or empty) binnings are
/// degenerate and have no regular bins.
pub const MAX_BINS: usize = 1 << 24;

/// Largest number of quadrature nodes per dimension per bin used by
/// [`SphereBinning::integrate`]; larger requests are clamped to it.
pub const MAX_SUB: usize = 256;

/// A θ × φ histogram layout over the unit sphere (see the module doc for the geometry).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SphereBinning {
    /// Number of strips in θ, uniform in cos θ (each 2/theta_bins wide in cos θ).
    pub theta_bins: usize,
    /// Number of sectors in φ, uniform in φ (each 2π/phi_bins rad wide).
    pub phi_bins: usize,
}

impl SphereBinning {
    /// Number of regular bins, theta_bins·phi_bins; 0 for a degenerate binning (either
    /// count 0, or more than [`MAX_BINS`] bins). It is also the index of the
    /// invalid-direction bin, so vectors returned by `count` and `integrate` have length
    /// `n_bins() + 1`.
    pub fn n_bins(&self) -> usize {
        match self.theta_bins.checked_mul(self.phi_bins) {
            Some(n) if n > 0 && n <= MAX_BINS => n,
            _ => 0,
        }
    }

    /// Solid angle of each regular bin in steradians (4π / n_bins), or 0 when degenerate.
    pub fn bin_solid_angle(&self) -> f64 {
        match self.n_bins() {
            0 => 0.0,
            n => 4.0 * std::f64::consts::PI / n as f64,
        }
    }

    /// Bin index of direction `w` (need not be unit length: only its direction is used).
    /// θ is the angle from +z in [0, π], φ = atan2(y, x) in [0, 2π). A direction exactly
    /// on the equator (z = 0) belongs to the strip above it. Zero, infinite or NaN
    /// directions, and every direction of a degenerate binning, map to the
    /// invalid-direction bin `n_bins()`.
    pub fn bin(&self, w: [f64; 3]) -> usize {
        let n = self.n_bins();
        if n == 0 {
            return 0;
        }
        let scale = w[0].abs().max(w[1].abs()).max(w[2].abs());
        if w.iter().any(|c| !c.is_finite()) || scale == 0.0 {
            return n;
        }
        let [x, y, z] = w.map(|c| c / scale);
        let cos_theta = (z / (x * x + y * y + z * z).sqrt()).clamp(-1.0, 1.0);
        let t = self.theta_bins;
        let half = t as f64 / 2.0;
        // Strip i covers cos θ in [1 − 2(i+1)/T, 1 − 2i/T] (equal-area strips); for z >= 0
        // count from the bottom so that tiny positive z never rounds into the strip below.
        let strip = if cos_theta >= 0.0 {
            let from_bottom = (((1.0 + cos_theta) * half) as usize).min(t - 1);
            t - 1 - from_bottom
        } else {
            (((1.0 - cos_theta) * half) as usize).min(t - 1)
        };
        let mut phi = y.atan2(x);
        if phi < 0.0 {
            phi += std::f64::consts::TAU;
        }
        let p = self.phi_bins;
        // Sector j covers φ in [2πj/P, 2π(j+1)/P) (uniform in φ by definition).
        let sector = ((phi / std::f64::consts::TAU * p as f64) as usize).min(p - 1);
        strip * p + sector
    }

    /// Histogram of `samples` (directions): counts per bin, length `n_bins() + 1`, the last
    /// entry counting invalid directions. Counts saturate at `u64::MAX`.
    pub fn count(&self, samples: impl IntoIterator<Item = [f64; 3]>) -> Vec<u64> {
        let mut counts = vec![0u64; self.n_bins() + 1];
        for w in samples {
            let c = &mut counts[self.bin(w)];
            *c = c.saturating_add(1);
        }
        counts
    }

    /// Expected probability mass per bin, ∫_bin pdf dω (dimensionless), for a pdf with
    /// respect to solid angle (1/sr), by tensor-product Gauss–Legendre quadrature in
    /// (cos θ, φ) with `sub` × `sub` nodes per bin (`sub` clamped into 1..=[`MAX_SUB`]).
    /// Integrating in cos θ makes dω = d(cos θ) dφ exact, so a pdf that is a polynomial of
    /// degree ≤ 2·sub − 1 in cos θ and constant in φ within each bin is integrated exactly.
    /// Bins that a support edge crosses (the pdf is 0 at some probes and positive at others)
    /// are re-integrated adaptively (`refine_edges`), since the plain rule's error there is
    /// first order in the node spacing.
    ///
    /// Length `n_bins() + 1`; the last (invalid-direction) entry is 0. Masses sum to the
    /// pdf's integral over the sphere (1 when normalised). The pdf's values are used as
    /// returned: negative or NaN values propagate and are rejected later by `chi2_gof`.
    pub fn integrate(&self, pdf: impl Fn([f64; 3]) -> f64, sub: usize) -> Vec<f64> {
        let r: Result<Vec<f64>, std::convert::Infallible> =
            self.integrate_batched(|w| Ok(w.iter().map(|&w| pdf(w)).collect()), sub);
        match r {
            Ok(m) => m,
            Err(e) => match e {},
        }
    }

    /// [`SphereBinning::integrate`] with the pdf evaluated a strip of bins at a time (for
    /// models answering batches); the same sums in the same order, so the same bits.
    pub fn integrate_batched<E>(
        &self,
        mut pdf: impl FnMut(&[[f64; 3]]) -> Result<Vec<f64>, E>,
        sub: usize,
    ) -> Result<Vec<f64>, E> {
        let n = self.n_bins();
        let mut mass = vec![0.0; n + 1];
        if n == 0 {
            return Ok(mass);
        }
        let (nodes, weights) = gauss_legendre(sub.clamp(1, MAX_SUB));
        let (t, p) = (self.theta_bins, self.phi_bins);
        let dc = 2.0 / t as f64;
        let dphi = std::f64::consts::TAU / p as f64;
        let per_bin = nodes.len() * nodes.len() + 4 * nodes.len();
        let mut points = Vec::with_capacity(p * per_bin);
        let mut edges = Vec::new();
        for strip in 0..t {
            let c_hi = 1.0 - strip as f64 * dc;
            points.clear();
            let cells: Vec<Cell> = (0..p)
                .map(|sector| Cell {
                    bin: strip * p + sector,
                    c: [c_hi - dc, c_hi],
                    phi: [sector as f64 * dphi, (sector + 1) as f64 * dphi],
                    polar: 0,
                })
                .collect();
            for cell in &cells {
                cell.probes(&nodes, nodes.len(), &mut points);
            }
            let values = pdf(&points)?;
            for (cell, v) in cells.iter().zip(values.chunks(per_bin)) {
                mass[cell.bin] = cell.integral(&nodes, &weights, v);
                if straddles(v) {
                    edges.push(*cell);
                }
            }
        }
        if !edges.is_empty() {
            for (bin, m) in refine_edges(&mut pdf, &edges)? {
                mass[bin] = m;
            }
        }
        Ok(mass)
    }
}

/// A symmetric 15-point rule from its first 8 entries (the 8th at x = 0): the others are their
/// mirror images, negated for nodes.
const fn mirror(half: [f64; 8], negate: bool) -> [f64; 15] {
    let mut out = [0.0; 15];
    let mut i = 0;
    while i < 8 {
        out[i] = if negate { -half[i] } else { half[i] };
        out[14 - i] = half[i];
        i += 1;
    }
    out
}

/// Gauss–Kronrod pair on [−1, 1]: the 15-point Kronrod extension of the 7-point Gauss rule
/// (Piessens et al. 1983, QUADPACK, routine QK15). Nodes in increasing order; the Gauss nodes
/// are every other one, starting at the second.
#[allow(clippy::excessive_precision)] // the published digits, as printed
const KRONROD_NODES: [f64; 15] = mirror(
    [
        0.991_455_371_120_812_639_206_854_697_526_329,
        0.949_107_912_342_758_524_526_189_684_047_851,
        0.864_864_423_359_769_072_789_712_788_640_926,
        0.741_531_185_599_394_439_863_864_773_280_788,
        0.586_087_235_467_691_130_294_144_845_693_013,
        0.405_845_151_377_397_166_906_606_412_076_961,
        0.207_784_955_007_898_467_600_689_403_773_245,
        0.0,
    ],
    true,
);

/// Kronrod weights for [`KRONROD_NODES`] (QUADPACK QK15).
#[allow(clippy::excessive_precision)] // the published digits, as printed
const KRONROD_WEIGHTS: [f64; 15] = mirror(
    [
        0.022_935_322_010_529_224_963_732_008_058_970,
        0.063_092_092_629_978_553_290_700_663_189_204,
        0.104_790_010_322_250_183_839_876_322_541_518,
        0.140_653_259_715_525_918_745_189_590_510_238,
        0.169_004_726_639_267_902_826_583_426_598_550,
        0.190_350_578_064_785_409_913_256_402_421_014,
        0.204_432_940_075_298_892_414_161_999_234_649,
        0.209_482_141_084_727_828_012_999_174_891_714,
    ],
    false,
);

/// Weights of the embedded 7-point Gauss rule, on the odd-indexed [`KRONROD_NODES`] (QUADPACK
/// QK15), zero elsewhere.
#[allow(clippy::excessive_precision)] // the published digits, as printed
const GAUSS7_IN_KRONROD: [f64; 15] = mirror(
    [
        0.0,
        0.129_484_966_168_869_693_270_611_432_679_082,
        0.0,
        0.279_705_391_489_276_667_901_467_771_423_780,
        0.0,
        0.381_830_050_505_118_944_950_369_775_488_975,
        0.0,
        0.417_959_183_673_469_387_755_102_040_816_327,
    ],
    false,
);

/// Probes per side of a cell in the adaptive rule (edge detection between the nodes).
const ADAPTIVE_SIDE_PROBES: usize = 32;

/// Levels of 2×2 splits the adaptive rule may take in a smooth bin whose two estimates
/// disagree (cells down to 1/2^5 of a bin's side).
const SMOOTH_DEPTH: usize = 5;

impl SphereBinning {
    /// Expected probability mass per bin, as [`SphereBinning::integrate_batched`], by an
    /// adaptive rule that spends pdf queries where they are needed: each bin gets the tensor
    /// 15-point Gauss–Kronrod rule with its embedded 7-point Gauss rule (225 nodes and 60 side
    /// probes, against 1152 for the fixed 32×32 rule); a bin where the two estimates differ by
    /// more than its tolerance `rel_tol`·|estimate| + `abs_tol` is split 2×2 and each cell
    /// integrated the same way against its share of the tolerance (by area), recursively (at
    /// most five (`SMOOTH_DEPTH`) levels, then the Kronrod value is kept), and
    /// a bin a support edge crosses is re-integrated as in the fixed rule (`refine_edges`). The
    /// Kronrod value is kept, and its error is in practice far below the difference that
    /// triggers a split (Piessens et al. 1983, §2.2.1). Same length and layout as the fixed
    /// rule's result; the same inputs give the same bits.
    pub fn integrate_adaptive_batched<E>(
        &self,
        mut pdf: impl FnMut(&[[f64; 3]]) -> Result<Vec<f64>, E>,
        rel_tol: f64,
        abs_tol: f64,
    ) -> Result<Vec<f64>, E> {
        let n = self.n_bins();
        let mut mass = vec![0.0; n + 1];
        if n == 0 {
            return Ok(mass);
        }
        let (t, p) = (self.theta_bins, self.phi_bins);
        let dc = 2.0 / t as f64;
        let dphi = std::f64::consts::TAU / p as f64;
        let per_cell = 15 * 15 + 4 * ADAPTIVE_SIDE_PROBES;
        let mut edges = Vec::new();
        let mut tolerance = vec![0.0; n];
        let mut level: Vec<Cell> = Vec::new();
        // the bins, a strip's worth at a time at the first level, then the split cells
        for strip in 0..t {
            let c_hi = 1.0 - strip as f64 * dc;
            // the first and last strips end exactly at the poles
            let c = [if strip + 1 == t { -1.0 } else { c_hi - dc }, c_hi];
            let polar = if strip == 0 {
                1
            } else if strip + 1 == t {
                -1
            } else {
                0
            };
            level.extend((0..p).map(|sector| Cell {
                bin: strip * p + sector,
                c,
                phi: [sector as f64 * dphi, (sector + 1) as f64 * dphi],
                polar: if t == 1 { 0 } else { polar },
            }));
        }
        let batch_cells = (EDGE_BATCH / per_cell).max(p);
        for depth in 0..=SMOOTH_DEPTH {
            let mut next = Vec::new();
            let mut points = Vec::with_capacity(batch_cells * per_cell);
            for chunk in level.chunks(batch_cells) {
                points.clear();
                for cell in chunk {
                    cell.probes(&KRONROD_NODES, ADAPTIVE_SIDE_PROBES, &mut points);
                }
                let values = pdf(&points)?;
                for (cell, v) in chunk.iter().zip(values.chunks(per_cell)) {
                    if straddles(v) {
                        // a support edge crosses the bin (or a split cell of it)
                        edges.push(*cell);
                        continue;
                    }
                    let k = cell.integral(&KRONROD_NODES, &KRONROD_WEIGHTS, v);
                    let g = cell.integral(&KRONROD_NODES, &GAUSS7_IN_KRONROD, v);
                    if depth == 0 {
                        tolerance[cell.bin] = rel_tol * k.abs() + abs_tol;
                    }
                    // the bin's tolerance shared by area: a cell 2^-depth of the bin's side
                    let share = tolerance[cell.bin] * 0.25f64.powi(depth as i32);
                    if depth < SMOOTH_DEPTH && (k - g).abs() > share {
                        next.extend(cell.split(2));
                    } else {
                        mass[cell.bin] += k;
                    }
                }
            }
            level = next;
            if level.is_empty() {
                break;
            }
        }
        if !edges.is_empty() {
            for (bin, m) in refine_edges(&mut pdf, &edges)? {
                mass[bin] += m;
            }
        }
        Ok(mass)
    }
}

/// A rectangle in (cos θ, φ) belonging to one bin.
#[derive(Debug, Clone, Copy)]
struct Cell {
    bin: usize,
    c: [f64; 2],
    phi: [f64; 2],
    /// +1 (−1): the cell touches the pole c = 1 (c = −1) and its nodes are placed in
    /// s = √(1 ∓ c), where the pdf is smooth (in c it goes as √(1 − c) at the pole, which
    /// slows any polynomial rule); 0: nodes in c.
    polar: i8,
}

impl Cell {
    /// Appends the directions where the pdf is probed: the tensor Gauss–Legendre nodes, then
    /// `k` points along each side, inset by 1e-9 of the cell (on a bin boundary the pdf
    /// belongs to the neighbour), which see an edge that clips a corner between the nodes.
    fn probes(&self, nodes: &[f64], k: usize, out: &mut Vec<[f64; 3]>) {
        let dir = |c: f64, phi: f64| {
            let c = c.clamp(-1.0, 1.0);
            let s = (1.0 - c * c).max(0.0).sqrt();
            [s * phi.cos(), s * phi.sin(), c]
        };
        let (cm, ch) = (0.5 * (self.c[0] + self.c[1]), 0.5 * (self.c[1] - self.c[0]));
        let (pm, ph) = (
            0.5 * (self.phi[0] + self.phi[1]),
            0.5 * (self.phi[1] - self.phi[0]),
        );
        // each node φ's (cos, sin) once per cell, not once per node pair: the same arguments,
        // so the same bits
        let azimuths: Vec<(f64, f64)> = nodes
            .iter()
            .map(|&xp| {
                let phi = pm + ph * xp;
                (phi.cos(), phi.sin())
            })
            .collect();
        for &xu in nodes {
            let c = self.node_c(xu).0.clamp(-1.0, 1.0);
            let s = (1.0 - c * c).max(0.0).sqrt();
            out.extend(azimuths.iter().map(|&(cos, sin)| [s * cos, s * sin, c]));
        }
        let inset = 1.0 - 1e-9;
        for i in 0..k {
            let t = 2.0 * (i as f64 + 0.5) / k as f64 - 1.0;
            out.push(dir(cm - ch * inset, pm + ph * t));
            out.push(dir(cm + ch * inset, pm + ph * t));
            out.push(dir(cm + ch * t, pm - ph * inset));
            out.push(dir(cm + ch * t, pm + ph * inset));
        }
    }

    /// cos θ at node x ∈ [−1, 1] and dc/dx there: affine in c, or (polar cells) affine in
    /// s = √(1 ∓ c), c = ±(1 − s²), dc/dx = 2s·ds/dx.
    fn node_c(&self, x: f64) -> (f64, f64) {
        match self.polar {
            0 => {
                let (cm, ch) = (0.5 * (self.c[0] + self.c[1]), 0.5 * (self.c[1] - self.c[0]));
                (cm + ch * x, ch)
            }
            pole => {
                let sign = pole as f64;
                // s runs from 0 at the pole to s_far at the other end of the cell
                let far = if pole > 0 { self.c[0] } else { self.c[1] };
                let s_far = (1.0 - sign * far).max(0.0).sqrt();
                let s = 0.5 * s_far * (1.0 + x);
                (sign * (1.0 - s * s), s * s_far)
            }
        }
    }

    /// ∫ pdf over the cell from the node values (the first nodes² of `v`, `weights` those of
    /// the nodes): Gauss–Legendre (Abramowitz & Stegun 1964, eq. 25.4.29) mapped to the cell,
    /// ∫ f ≈ Σ w_i (dc/dx)_i Σ w_j (Δφ/2) f(c_i, φ_j), with dω = d(cos θ) dφ.
    fn integral(&self, nodes: &[f64], weights: &[f64], v: &[f64]) -> f64 {
        if self.polar == 0 {
            let mut sum = 0.0;
            let mut k = 0;
            for &wu in weights {
                for &wp in weights {
                    sum += wu * wp * v[k];
                    k += 1;
                }
            }
            return sum * 0.25 * (self.c[1] - self.c[0]) * (self.phi[1] - self.phi[0]);
        }
        let ph = 0.5 * (self.phi[1] - self.phi[0]);
        let mut sum = 0.0;
        let mut k = 0;
        for (&xu, &wu) in nodes.iter().zip(weights) {
            let mut row = 0.0;
            for &wp in weights {
                row += wp * v[k];
                k += 1;
            }
            sum += wu * self.node_c(xu).1 * row;
        }
        sum * ph
    }

    /// The 2×2 cells of equal size that make up this one.
    fn split(&self, n: usize) -> impl Iterator<Item = Cell> + '_ {
        let (dc, dp) = (
            (self.c[1] - self.c[0]) / n as f64,
            (self.phi[1] - self.phi[0]) / n as f64,
        );
        (0..n * n).map(move |k| {
            let (row, col) = (k / n, k % n);
            let (i, j) = (row as f64, col as f64);
            // the cells at the ends keep the parent's ends exactly (a pole stays a pole)
            let c_hi = if row + 1 == n {
                self.c[1]
            } else {
                self.c[0] + (i + 1.0) * dc
            };
            let polar = match self.polar {
                1 if row + 1 == n => 1,
                -1 if row == 0 => -1,
                _ => 0,
            };
            Cell {
                bin: self.bin,
                c: [self.c[0] + i * dc, c_hi],
                phi: [self.phi[0] + j * dp, self.phi[0] + (j + 1.0) * dp],
                polar,
            }
        })
    }
}

/// Some probes see pdf 0 and some pdf > 0: a support edge crosses the cell.
fn straddles(v: &[f64]) -> bool {
    v.iter().any(|x| *x > 0.0) && v.contains(&0.0)
}

/// First split of an edge bin (8×8 cells), then up to `EDGE_DEPTH` − 3 levels of 2×2 splits
/// where a cell still straddles: cells down to 1/2^EDGE_DEPTH of a bin's side.
const EDGE_DEPTH: usize = 7;

/// Gauss–Legendre nodes per dimension, and probes per side, in each refined cell.
const EDGE_NODES: usize = 4;

/// Most directions handed to the pdf in one call while refining.
const EDGE_BATCH: usize = 1 << 16;

/// Most pdf evaluations spent on refinement; past it, straddling cells are integrated as
/// they are (bounded time for pathological pdfs, such as one that is zero at scattered points).
const EDGE_BUDGET: usize = 1 << 24;

/// Re-integrates the bins a support edge crosses (a light's silhouette, a cone's rim), where
/// the tensor rule's error is first order in the node spacing: about 1e-3 of a unit pdf's
/// mass for a cone over 24×48 bins, 7e-6 after refinement (the unit test below). An edge bin
/// is split 8×8, then 2×2 recursively where a cell's probes (nodes and sides) still disagree;
/// a pdf jump between two non-zero values is not refined. Returns (bin, mass) per edge bin.
fn refine_edges<E>(
    pdf: &mut impl FnMut(&[[f64; 3]]) -> Result<Vec<f64>, E>,
    edges: &[Cell],
) -> Result<Vec<(usize, f64)>, E> {
    let (nodes, weights) = gauss_legendre(EDGE_NODES);
    let per_cell = EDGE_NODES * EDGE_NODES + 4 * EDGE_NODES;
    let mut totals: Vec<(usize, f64)> = edges.iter().map(|e| (e.bin, 0.0)).collect();
    let slot: std::collections::HashMap<usize, usize> =
        edges.iter().enumerate().map(|(i, e)| (e.bin, i)).collect();
    let mut level: Vec<Cell> = edges.iter().flat_map(|e| e.split(8)).collect();
    let mut spent = 0usize;
    for depth in 3..=EDGE_DEPTH {
        let mut values = Vec::with_capacity(level.len() * per_cell);
        let mut points = Vec::with_capacity(EDGE_BATCH);
        for chunk in level.chunks(EDGE_BATCH / per_cell) {
            points.clear();
            for cell in chunk {
                cell.probes(&nodes, EDGE_NODES, &mut points);
            }
            values.extend(pdf(&points)?);
        }
        spent += values.len();
        let last = depth == EDGE_DEPTH || spent >= EDGE_BUDGET;
        let mut next = Vec::new();
        for (cell, v) in level.iter().zip(values.chunks(per_cell)) {
            if !last && straddles(v) {
                next.extend(cell.split(2));
            } else {
                totals[slot[&cell.bin]].1 += cell.integral(&nodes, &weights, v);
            }
        }
        level = next;
        if level.is_empty() {
            break;
        }
    }
    Ok(totals)
}

/// Gauss–Legendre nodes and weights on [−1, 1] for `n` >= 1 points: nodes are the roots
/// of P_n found by Newton's method from Tricomi's initial guesses.
fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Initial guess θ = π(ν − 1/4)/(n + 1/2), ν = i + 1: the middle of the bracket
        // π(ν − 1/2)/(n + 1/2) < θ_ν < πν/(n + 1/2) (Szegő 1939, Orthogonal Polynomials, §6.21).
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_with_derivative(n, x);
            dp = d;
            let step = p / d;
            x -= step;
            if step.abs() <= 1e-15 {
                break;
            }
        }
        let (_, d) = legendre_with_derivative(n, x);
        if d.is_finite() && d != 0.0 {
            dp = d;
        }
        // Weight w_i = 2 / ((1 − x_i²) P_n'(x_i)²) (Abramowitz & Stegun 1964, eq. 25.4.29).
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = -x;
        weights[i] = w;
        nodes[n - 1 - i] = x;
        weights[n - 1 - i] = w;
    }
    (nodes, weights)
}

/// P_n(x) and P_n'(x) by Bonnet's recurrence (j+1)P_{j+1} = (2j+1)x P_j − j P_{j−1}
/// (Abramowitz & Stegun 1964, eq. 22.7.10) and P_n' = n(x P_n − P_{n−1})/(x² − 1)
/// (A&S eq. 22.8.5), for |x| < 1.
fn legendre_with_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p_prev, mut p) = (1.0, x);
    for j in 1..n {
        let jf = j as f64;
        let next = ((2.0 * jf + 1.0) * x * p - jf * p_prev) / (jf + 1.0);
        p_prev = p;
        p = next;
    }
    let d = n as f64 * (x * p - p_prev) / (x * x - 1.0);
    (p, d)
}

#[cfg(test)]
mod tests {
    use super::super::chi2::chi2_gof;
    use super::*;
    use crate::math::rng::SampleStream;
    use std::f64::consts::{FRAC_1_PI, PI, TAU};

    /// Cosine-weighted hemisphere direction by Malley's method: uniform point on the unit
    /// disk lifted to the hemisphere (Pharr, Jakob & Humphreys, PBRT 3rd ed., §13.6.3).
    fn sample_cosine(rng: &mut SampleStream) -> [f64; 3] {
        let (u1, u2) = (rng.next_f64(), rng.next_f64());
        let r = u1.sqrt();
        let phi = TAU * u2;
        [r * phi.cos(), r * phi.sin(), (1.0 - u1).sqrt()]
    }

    fn cosine_pdf(w: [f64; 3]) -> f64 {
        w[2].max(0.0) * FRAC_1_PI
    }

    fn uniform_hemisphere_pdf(w: [f64; 3]) -> f64 {
        if w[2] >= 0.0 {
            0.5 / PI
        } else {
            0.0
        }
    }

    fn scaled(mass: &[f64], n: usize) -> Vec<f64> {
        mass.iter().map(|m| m * n as f64).collect()
    }

    #[test]
    fn gauss_legendre_nodes_and_weights() {
        // 2-point rule: ±1/√3, weights 1; 3-point: 0, ±√(3/5), weights 8/9, 5/9.
        let (x, w) = gauss_legendre(2);
        assert!((x[1] - 1.0 / 3f64.sqrt()).abs() < 1e-15 && (w[0] - 1.0).abs() < 1e-14);
        let (x, w) = gauss_legendre(3);
        assert!(x[1].abs() < 1e-15 && (w[1] - 8.0 / 9.0).abs() < 1e-14);
        assert!((x[2] - 0.6f64.sqrt()).abs() < 1e-15 && (w[2] - 5.0 / 9.0).abs() < 1e-14);
        for n in [1, 4, 7, 20, 64, MAX_SUB] {
            let (x, w) = gauss_legendre(n);
            assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-12, "n={n}");
            // Exact for x^(2n-2) when n > 1: ∫ x^(2n−2) = 2/(2n−1).
            let k = 2 * n as i32 - 2;
            let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k)).sum();
            assert!((q - 2.0 / (k as f64 + 1.0)).abs() < 1e-12, "n={n} q={q}");
        }
    }

    #[test]
    fn gauss_kronrod_pair_integrates_polynomials_to_their_degree() {
        // 15-point Kronrod: exact to degree 22 (3n + 1 for n = 7); 7-point Gauss: degree 13.
        let moment = |w: &[f64; 15], k: i32| -> f64 {
            KRONROD_NODES
                .iter()
                .zip(w)
                .map(|(x, w)| w * x.powi(k))
                .sum()
        };
        for k in 0..=22 {
            let exact = if k % 2 == 0 {
                2.0 / (k as f64 + 1.0)
            } else {
                0.0
            };
            assert!(
                (moment(&KRONROD_WEIGHTS, k) - exact).abs() < 1e-14,
                "K15 x^{k}"
            );
            if k <= 13 {
                let g = moment(&GAUSS7_IN_KRONROD, k);
                assert!((g - exact).abs() < 1e-14, "G7 x^{k}");
            }
        }
        // and not beyond: the rules differ on x^24 and x^14
        assert!((moment(&KRONROD_WEIGHTS, 24) - 2.0 / 25.0).abs() > 1e-9);
        assert!((moment(&GAUSS7_IN_KRONROD, 14) - 2.0 / 15.0).abs() > 1e-6);
        // the Gauss nodes are those of the 7-point rule
        let (x7, w7) = gauss_legendre(7);
        for i in 0..7 {
            assert!((KRONROD_NODES[2 * i + 1] - x7[i]).abs() < 1e-15);
            assert!((GAUSS7_IN_KRONROD[2 * i + 1] - w7[i]).abs() < 1e-14);
        }
    }

    /// Von Mises–Fisher lobe around `mu` with concentration `kappa` (sr⁻¹):
    /// κ/(2π(1 − e^{−2κ})) exp(κ(μ·w − 1)) (Fisher 1953, Proc. R. Soc. A 217).
    fn vmf(mu: [f64; 3], kappa: f64) -> impl Fn([f64; 3]) -> f64 {
        move |w| {
            let d = mu[0] * w[0] + mu[1] * w[1] + mu[2] * w[2];
            kappa / (TAU * (1.0 - (-2.0 * kappa).exp())) * (kappa * (d - 1.0)).exp()
        }
    }

    #[test]
    fn the_adaptive_rule_agrees_with_a_fine_fixed_rule_for_fewer_queries() {
        let s = 0.6f64.sqrt();
        let cone = |w: [f64; 3]| {
            if w[2] > 0.8 {
                1.0 / (TAU * 0.2)
            } else {
                0.0
            }
        };
        type Pdf = Box<dyn Fn([f64; 3]) -> f64>;
        let cases: Vec<(&str, Pdf)> = vec![
            ("cosine", Box::new(cosine_pdf)),
            ("cone", Box::new(cone)),
            ("broad lobe", Box::new(vmf([s, 0.0, 0.4f64.sqrt()], 10.0))),
            ("lobe at the pole", Box::new(vmf([0.0, 0.0, 1.0], 30.0))),
            (
                "narrow lobe",
                Box::new(vmf([0.3, -0.5, 0.812_403_840_463_596], 2000.0)),
            ),
        ];
        for (name, pdf) in &cases {
            let count = std::cell::Cell::new(0usize);
            let counted = |w: &[[f64; 3]]| -> Result<Vec<f64>, ()> {
                count.set(count.get() + w.len());
                Ok(w.iter().map(|&w| pdf(w)).collect())
            };
            // accuracy: against 256×256 nodes per bin, on a coarser binning to keep it quick
            let coarse = SphereBinning {
                theta_bins: 12,
                phi_bins: 24,
            };
            let reference = coarse.integrate_batched(counted, MAX_SUB).unwrap();
            let adaptive = coarse
                .integrate_adaptive_batched(counted, 1e-6, 1e-12)
                .unwrap();
            let worst = reference
                .iter()
                .zip(&adaptive)
                .map(|(f, a)| (f - a).abs())
                .fold(0.0, f64::max);
            // the cone's edge bins are refined alike by both rules (on bins this coarse, to
            // 7e-4 of its mass), so there they agree with each other, not with 1
            let total: f64 = adaptive.iter().sum();
            let (bin_tol, expected_total) = if *name == "cone" {
                (1e-5, reference.iter().sum())
            } else {
                (1e-10, 1.0)
            };
            assert!(worst < bin_tol, "{name}: bins differ by up to {worst:e}");
            assert!(
                (total - expected_total).abs() < 1e-9,
                "{name}: total {total}"
            );
            // cost: against the fixed 32×32 rule the chi-square check used before
            let b = SphereBinning {
                theta_bins: 24,
                phi_bins: 48,
            };
            count.set(0);
            b.integrate_batched(counted, 32).unwrap();
            let fixed_queries = count.replace(0);
            b.integrate_adaptive_batched(counted, 1e-6, 1e-12).unwrap();
            let adaptive_queries = count.get();
            // the edge refinement, the same in both, dominates the cone's queries and the
            // narrow lobe's (its pdf underflows to 0 a few degrees out: an edge)
            let gain = if matches!(*name, "cone" | "narrow lobe") {
                1
            } else {
                3
            };
            assert!(
                adaptive_queries * gain < fixed_queries,
                "{name}: {adaptive_queries} queries, fixed rule {fixed_queries}"
            );
            eprintln!(
                "{name}: {adaptive_queries} queries (fixed 32x32: {fixed_queries}); bins within {worst:.1e} of 256x256 nodes"
            );
        }
    }

    #[test]
    fn bin_layout() {
        let b = SphereBinning {
            theta_bins: 4,
            phi_bins: 8,
        };
        assert_eq!(b.n_bins(), 32);
        assert_eq!(b.bin([0.0, 0.0, 1.0]), 0, "+z is strip 0, sector 0");
        assert_eq!(b.bin([0.0, 0.0, -1.0]), 3 * 8, "-z is the last strip");
        assert_eq!(b.bin([0.0, 0.0, 5.0]), 0, "length does not matter");
        assert_eq!(b.bin([1e-300, 0.0, 1e-300]), b.bin([1.0, 0.0, 1.0]));
        assert_eq!(b.bin([1e300, 0.0, 1e300]), b.bin([1.0, 0.0, 1.0]));
        // cos θ = 0.6: strip floor((1 − 0.6)·2) = 0; cos θ = 0.4: strip 1.
        assert_eq!(b.bin([0.8, 0.0, 0.6]) / 8, 0);
        assert_eq!(b.bin([0.916_515, 0.0, 0.4]) / 8, 1);
        // Equator belongs to the upper hemisphere; a hair below goes below.
        assert_eq!(b.bin([1.0, 0.0, 0.0]) / 8, 1);
        assert_eq!(b.bin([1.0, 0.0, 1e-17]) / 8, 1);
        assert_eq!(b.bin([1.0, 0.0, -1e-17]) / 8, 2);
        // φ sectors: +y is φ = π/2 -> sector 2; φ just below 2π -> sector 7.
        assert_eq!(b.bin([0.0, 1.0, 0.0]) % 8, 2);
        assert_eq!(b.bin([1.0, -1e-18, 0.0]) % 8, 7);
        assert_eq!(b.bin([1.0, -0.0, 0.0]) % 8, 0);
        assert_eq!(b.bin([-1.0, 0.0, 0.0]) % 8, 4);
    }

    #[test]
    fn invalid_directions_and_degenerate_binnings() {
        let b = SphereBinning {
            theta_bins: 4,
            phi_bins: 8,
        };
        for w in [[0.0; 3], [f64::NAN, 0.0, 1.0], [f64::INFINITY, 0.0, 0.0]] {
            assert_eq!(b.bin(w), 32);
        }
        for d in [
            SphereBinning {
                theta_bins: 0,
                phi_bins: 8,
            },
            SphereBinning {
                theta_bins: 8,
                phi_bins: 0,
            },
            SphereBinning {
                theta_bins: usize::MAX,
                phi_bins: 2,
            },
            SphereBinning {
                theta_bins: MAX_BINS,
                phi_bins: 2,
            },
        ] {
            assert_eq!(d.n_bins(), 0);
            assert_eq!(d.bin([0.0, 0.0, 1.0]), 0);
            assert_eq!(d.count([[0.0, 0.0, 1.0]; 3]), vec![3]);
            assert_eq!(d.integrate(cosine_pdf, 4), vec![0.0]);
            assert_eq!(d.bin_solid_angle(), 0.0);
        }
    }

    #[test]
    fn uniform_sphere_pdf_gives_equal_bins() {
        let b = SphereBinning {
            theta_bins: 10,
            phi_bins: 12,
        };
        let m = b.integrate(|_| 0.25 * FRAC_1_PI, 3);
        assert_eq!(m.len(), 121);
        assert_eq!(m[120], 0.0);
        for &x in &m[..120] {
            assert!((x - 1.0 / 120.0).abs() < 1e-15, "{x}");
        }
        assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-13);
        assert!((b.bin_solid_angle() - 4.0 * PI / 120.0).abs() < 1e-15);
    }

    #[test]
    fn cosine_hemisphere_pdf_integrates_exactly() {
        let b = SphereBinning {
            theta_bins: 8,
            phi_bins: 6,
        };
        let m = b.integrate(cosine_pdf, 2);
        assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-13);
        // Strip [a, b] in cos θ, one sector: (b² − a²)/2 · (2π/6)/π.
        for strip in 0..8 {
            let (hi, lo) = (1.0 - strip as f64 * 0.25, 0.75 - strip as f64 * 0.25);
            let want = if lo >= 0.0 {
                (hi * hi - lo * lo) / 2.0 / 3.0
            } else {
                0.0
            };
            for sector in 0..6 {
                assert!(
                    (m[strip * 6 + sector] - want).abs() < 1e-15,
                    "{strip} {sector}"
                );
            }
        }
        // With sub = 1 (midpoint rule) the linear pdf is still exact.
        assert!((b.integrate(cosine_pdf, 1).iter().sum::<f64>() - 1.0).abs() < 1e-13);
    }

    #[test]
    fn anisotropic_pdfs_integrate_to_one() {
        let b = SphereBinning {
            theta_bins: 6,
            phi_bins: 16,
        };
        // ∫ 3z²/(4π) dω = 1: degree 2 in cos θ, exact for sub >= 2.
        let m = b.integrate(|w| 0.75 * FRAC_1_PI * w[2] * w[2], 2);
        assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-13);
        // ∫ 3x²/(4π) dω = 1: depends on φ, accurate but not exact.
        let m = b.integrate(|w| 0.75 * FRAC_1_PI * w[0] * w[0], 4);
        assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn cosine_samples_pass_against_cosine_pdf() {
        let b = SphereBinning {
            theta_bins: 8,
            phi_bins: 16,
        };
        let n = 50_000;
        let expected = scaled(&b.integrate(cosine_pdf, 4), n);
        for seed in [1, 2, 3] {
            let mut rng = SampleStream::new(seed, 0, 0);
            let counts = b.count((0..n).map(|_| sample_cosine(&mut rng)));
            assert_eq!(counts.iter().sum::<u64>(), n as u64);
            let r = chi2_gof(&counts, &expected, 5.0).unwrap();
            assert_eq!(r.zero_pdf_hits, 0);
            assert_eq!(r.dof, 63, "64 upper-hemisphere bins");
            assert!(r.p_value > 1e-3, "seed {seed}: {r:?}");
        }
    }

    #[test]
    fn cosine_samples_fail_against_wrong_pdfs() {
        let b = SphereBinning {
            theta_bins: 8,
            phi_bins: 16,
        };
        let n = 50_000;
        let mut rng = SampleStream::new(7, 0, 0);
        let counts = b.count((0..n).map(|_| sample_cosine(&mut rng)));
        // Wrong shape: uniform hemisphere.
        let r = chi2_gof(
            &counts,
            &scaled(&b.integrate(uniform_hemisphere_pdf, 4), n),
            5.0,
        );
        assert!(r.unwrap().p_value < 1e-6);
        // Right shape, wrong normalisation (integrates to 0.9).
        let r = chi2_gof(
            &counts,
            &scaled(&b.integrate(|w| 0.9 * cosine_pdf(w), 4), n),
            5.0,
        );
        assert!(r.unwrap().p_value < 1e-6);
        // Wrong support: pdf claims the lower hemisphere.
        let flipped = |w: [f64; 3]| cosine_pdf([w[0], w[1], -w[2]]);
        let r = chi2_gof(&counts, &scaled(&b.integrate(flipped, 4), n), 5.0).unwrap();
        assert_eq!(r.zero_pdf_hits, n as u64);
        assert_eq!(r.p_value, 0.0);
    }

    #[test]
    fn invalid_samples_fail_the_test() {
        let b = SphereBinning {
            theta_bins: 8,
            phi_bins: 16,
        };
        let n = 50_000;
        let mut rng = SampleStream::new(1, 0, 0);
        let mut samples: Vec<[f64; 3]> = (0..n).map(|_| sample_cosine(&mut rng)).collect();
        samples[123] = [f64::NAN, 0.0, 1.0];
        let counts = b.count(samples);
        assert_eq!(counts[b.n_bins()], 1);
        let r = chi2_gof(&counts, &scaled(&b.integrate(cosine_pdf, 4), n), 5.0).unwrap();
        assert_eq!(r.zero_pdf_hits, 1);
        assert_eq!(r.p_value, 0.0);
    }

    #[test]
    fn a_hard_edged_cone_integrates_to_one_where_the_plain_rule_misses() {
        // Uniform pdf over a cone of half-angle 0.2 rad around a tilted axis: solid angle
        // 2π(1 − cos α) (a spherical cap), pdf 1/Ω inside, 0 outside — edges cut ~40 bins.
        let axis = [0.7f64.sin(), 0.0, 0.7f64.cos()];
        let cos_a = 0.2f64.cos();
        let omega = TAU * (1.0 - cos_a);
        let cone = |w: [f64; 3]| {
            let d = w[0] * axis[0] + w[1] * axis[1] + w[2] * axis[2];
            if d >= cos_a {
                1.0 / omega
            } else {
                0.0
            }
        };
        let b = SphereBinning {
            theta_bins: 24,
            phi_bins: 48,
        };
        let total: f64 = b.integrate(cone, 32).iter().sum();
        assert!((total - 1.0).abs() < 2e-5, "refined total {total}");
        // Without refinement the same rule misses by ~1e-3 (what the refinement is for): a
        // single bin integrated by the plain rule straddling the rim.
        let plain: f64 = {
            let (x, w) = gauss_legendre(32);
            let (c0, c1) = (0.7f64.cos() - 0.05, 0.7f64.cos() + 0.25);
            let (p0, p1) = (-0.3f64, 0.3f64);
            let mut sum = 0.0;
            for (xu, wu) in x.iter().zip(&w) {
                let c: f64 = 0.5 * (c0 + c1) + 0.5 * (c1 - c0) * xu;
                let s = (1.0 - c * c).sqrt();
                for (xp, wp) in x.iter().zip(&w) {
                    let phi: f64 = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * xp;
                    sum += wu * wp * cone([s * phi.cos(), s * phi.sin(), c]);
                }
            }
            sum * 0.25 * (c1 - c0) * (p1 - p0)
        };
        assert!((plain - 1.0).abs() > 1e-4, "plain rule {plain}");
    }
}
