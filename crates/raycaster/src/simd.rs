//! [`Isa`]: the instruction set a hot loop is compiled for, chosen at run
//! time.
//!
//! The marching loops are written once, generic over `I: Isa`, with their
//! lane-wise steps as loops over fixed-size arrays of [`LANES`] values that
//! the compiler vectorises. Each loop is instantiated twice: for [`Portable`]
//! (the SSE2 every x86-64 has, or whatever the target is), and inside a
//! `#[target_feature(enable = "avx2")]` function for [`Avx2`], whose token
//! only [`Avx2::detect`] hands out. One binary so runs anywhere and uses
//! 8-wide vectors where the CPU has them. A loop over 16 lanes (the exact
//! iso mode's ray packets) says so with [`Kernel::WIDE`] and gets a third
//! copy compiled for AVX-512 too, used where the CPU has it (16 lanes a
//! register); the 8-lane loops stay on AVX2, which ran them faster. The
//! few operations the compiler
//! cannot produce from plain loops (a splat into the upper lanes, a gather, a
//! mask of lanes) are the trait's methods, one intrinsic each.
//!
//! Both copies do the same arithmetic in the same order (Rust never fuses a
//! multiply and an add on its own), so they give the same bits.

/// Values per vector: one AVX2 register of `f32`.
pub const LANES: usize = 8;

/// Code to run compiled for the best instruction set of this CPU: a hot loop
/// generic over the [`Isa`], handed to [`dispatch`].
pub trait Kernel {
    /// What the loop returns.
    type Output;
    /// Whether the loop works on 16 values at a time (the iso mode's ray
    /// packets), so that it runs in the AVX-512 copy where the CPU has
    /// AVX-512. Opt-in: the 8-lane loops of volume rendering ran slower
    /// compiled for AVX-512 than for AVX2.
    const WIDE: bool = false;
    /// Runs the loop; implementations are `#[inline(always)]`, so that the
    /// loop is compiled into each instruction set's copy of [`dispatch`].
    fn run<I: Isa>(self, isa: I) -> Self::Output;
}

/// Runs `kernel` in the AVX2 copy when the CPU has AVX2 (a
/// [`Kernel::WIDE`] one in the AVX-512 copy when it has that too), else in
/// the portable one: the one place a hot loop's instruction set is chosen.
#[inline]
pub fn dispatch<K: Kernel>(kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    match choice() {
        // SAFETY: the CPU has AVX2 and AVX-512 F/VL/BW/DQ (`choice`).
        AVX512 if K::WIDE => return unsafe { run_avx512(kernel, Avx2(())) },
        // SAFETY: the CPU has AVX2 (`choice`).
        AVX2 | AVX512 => return unsafe { run_avx2(kernel, Avx2(())) },
        _ => {}
    }
    kernel.run(Portable)
}

/// [`Kernel::run`] compiled with AVX-512 enabled as well, for a
/// [`Kernel::WIDE`] loop: the same code and the same `Avx2` operations,
/// with the compiler free to use 16-lane registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl,avx512bw,avx512dq")]
fn run_avx512<K: Kernel>(kernel: K, isa: Avx2) -> K::Output {
    kernel.run(isa)
}

/// [`Kernel::run`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_avx2<K: Kernel>(kernel: K, isa: Avx2) -> K::Output {
    kernel.run(isa)
}

/// An instruction set, as a token: a value of the type proves the CPU has
/// it.
pub trait Isa: Copy {
    /// Bit `l` set when `v[l] != 0`.
    fn nonzero_mask(self, v: &[u32; LANES]) -> u32;

    /// `out[l] = table[index[l]]`, with each index first clamped to the
    /// table (which must not be empty).
    fn gather(self, table: &[f32], index: &[u32; LANES]) -> [f32; LANES];

    /// `v` with lanes `from..` set to `x`.
    fn splat_from(self, v: [f32; LANES], x: f32, from: usize) -> [f32; LANES];
}

/// Any CPU: plain Rust, vectorised by the compiler as far as the baseline
/// instruction set allows (and SSE4.1's blend for [`Isa::splat_from`] when
/// the baseline has it, as the workspace's x86-64-v2 does: the compiler
/// turned the per-lane select into scalar code).
#[derive(Debug, Clone, Copy)]
pub struct Portable;

impl Isa for Portable {
    #[inline(always)]
    fn gather(self, table: &[f32], index: &[u32; LANES]) -> [f32; LANES] {
        let last = table.len() - 1;
        std::array::from_fn(|l| table[(index[l] as usize).min(last)])
    }

    #[inline(always)]
    fn splat_from(self, v: [f32; LANES], x: f32, from: usize) -> [f32; LANES] {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
        {
            use std::arch::x86_64::{
                __m128, _mm_blendv_ps, _mm_castsi128_ps, _mm_cmpgt_epi32, _mm_set_ps1,
                _mm_set1_epi32, _mm_setr_epi32,
            };
            // SAFETY: SSE4.1 is enabled for the whole build (the cfg above);
            // `[f32; 8]` and `[__m128; 2]` are both 32 bytes of plain data.
            unsafe {
                let halves: [__m128; 2] = std::mem::transmute(v);
                let from = _mm_set1_epi32(from as i32);
                let splat = _mm_set_ps1(x);
                let blend = |h: __m128, first: i32| {
                    let lanes = _mm_setr_epi32(first, first + 1, first + 2, first + 3);
                    let before = _mm_castsi128_ps(_mm_cmpgt_epi32(from, lanes));
                    _mm_blendv_ps(splat, h, before)
                };
                std::mem::transmute([blend(halves[0], 0), blend(halves[1], 4)])
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
        std::array::from_fn(|l| if l >= from { x } else { v[l] })
    }

    #[inline(always)]
    fn nonzero_mask(self, v: &[u32; LANES]) -> u32 {
        let mut m = 0;
        for (l, &x) in v.iter().enumerate() {
            m |= ((x != 0) as u32) << l;
        }
        m
    }
}

/// AVX2 (8 lanes of `f32`); only [`Avx2::detect`] makes one.
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
pub struct Avx2(());

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// The token, when this CPU has AVX2 and the environment variable
    /// `RAYCASTER_SIMD` is not `portable` (which forces the portable copies,
    /// to compare the two).
    #[inline]
    pub fn detect() -> Option<Self> {
        (choice() != PORTABLE).then_some(Avx2(()))
    }
}

/// [`choice`]s: the instruction sets a process can choose.
#[cfg(target_arch = "x86_64")]
const PORTABLE: u8 = 1;
#[cfg(target_arch = "x86_64")]
const AVX2: u8 = 2;
#[cfg(target_arch = "x86_64")]
const AVX512: u8 = 3;

/// The instruction set chosen for this process, decided once: AVX-512 (F,
/// VL, BW and DQ, with AVX2) when the CPU has it and the environment
/// variable `RAYCASTER_SIMD` is not `avx2`, else AVX2 when it has that and
/// `RAYCASTER_SIMD` is not `portable` (either forces the narrower copies,
/// to compare them), else portable.
#[cfg(target_arch = "x86_64")]
#[inline]
fn choice() -> u8 {
    use std::sync::atomic::{AtomicU8, Ordering};
    // 0: not decided yet.
    static CHOICE: AtomicU8 = AtomicU8::new(0);
    match CHOICE.load(Ordering::Relaxed) {
        0 => {
            let forced = std::env::var_os("RAYCASTER_SIMD");
            let c = if forced.as_ref().is_some_and(|v| v == "portable")
                || !std::is_x86_feature_detected!("avx2")
            {
                PORTABLE
            } else if forced.as_ref().is_some_and(|v| v == "avx2")
                || !(std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512vl")
                    && std::is_x86_feature_detected!("avx512bw")
                    && std::is_x86_feature_detected!("avx512dq"))
            {
                AVX2
            } else {
                AVX512
            };
            CHOICE.store(c, Ordering::Relaxed);
            c
        }
        c => c,
    }
}

#[cfg(target_arch = "x86_64")]
impl Isa for Avx2 {
    #[inline(always)]
    fn gather(self, table: &[f32], index: &[u32; LANES]) -> [f32; LANES] {
        // SAFETY: an `Avx2` exists only when the CPU has AVX2.
        unsafe { gather_avx2(table, index) }
    }

    #[inline(always)]
    fn nonzero_mask(self, v: &[u32; LANES]) -> u32 {
        // SAFETY: an `Avx2` exists only when the CPU has AVX2.
        unsafe { nonzero_mask_avx2(v) }
    }

    #[inline(always)]
    fn splat_from(self, v: [f32; LANES], x: f32, from: usize) -> [f32; LANES] {
        // SAFETY: an `Avx2` exists only when the CPU has AVX2.
        unsafe { splat_from_avx2(v, x, from) }
    }
}

/// A compare of the lane numbers with `from` and a `vblendvps`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn splat_from_avx2(v: [f32; LANES], x: f32, from: usize) -> [f32; LANES] {
    use std::arch::x86_64::{
        __m256, _mm256_blendv_ps, _mm256_castsi256_ps, _mm256_cmpgt_epi32, _mm256_set1_epi32,
        _mm256_set1_ps, _mm256_setr_epi32,
    };
    // SAFETY: `[f32; 8]` and `__m256` are both 32 bytes of plain data.
    let v: __m256 = unsafe { std::mem::transmute(v) };
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    // All ones in the lanes before `from` (`from` <= 8 fits an i32).
    let before = _mm256_cmpgt_epi32(_mm256_set1_epi32(from as i32), lanes);
    let out = _mm256_blendv_ps(_mm256_set1_ps(x), v, _mm256_castsi256_ps(before));
    // SAFETY: as above.
    unsafe { std::mem::transmute(out) }
}

/// A compare and a `vmovmskps`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn nonzero_mask_avx2(v: &[u32; LANES]) -> u32 {
    use std::arch::x86_64::{
        __m256i, _mm256_castsi256_ps, _mm256_cmpeq_epi32, _mm256_movemask_ps, _mm256_setzero_si256,
    };
    // SAFETY: `[u32; 8]` and `__m256i` are both 32 bytes of plain data.
    let v: __m256i = unsafe { std::mem::transmute(*v) };
    let zero = _mm256_cmpeq_epi32(v, _mm256_setzero_si256());
    !(_mm256_movemask_ps(_mm256_castsi256_ps(zero)) as u32) & 0xff
}

/// Clamps the indices with `vpminud`, then one `vgatherdps`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn gather_avx2(table: &[f32], index: &[u32; LANES]) -> [f32; LANES] {
    use std::arch::x86_64::{__m256i, _mm256_i32gather_ps, _mm256_min_epu32, _mm256_set1_epi32};
    assert!(!table.is_empty() && table.len() <= i32::MAX as usize);
    // SAFETY: `[u32; 8]` and `__m256i` are both 32 bytes of plain data.
    let index: __m256i = unsafe { std::mem::transmute(*index) };
    let last = _mm256_set1_epi32(table.len() as i32 - 1);
    let index = _mm256_min_epu32(index, last);
    // SAFETY: every index is at most `table.len() − 1` after the unsigned
    // minimum, so each of the eight 4-byte reads lies inside `table`; the
    // result is 32 bytes of plain data reinterpreted as `[f32; 8]`.
    unsafe { std::mem::transmute(_mm256_i32gather_ps::<4>(table.as_ptr(), index)) }
}

/// The bit set of the lanes `v[l] != 0`. (The packet walk's `lane_mask`,
/// with the CPU's mask instruction, ran no faster where the frame driver
/// sets up a block of rays in the AVX-512 copy, and 0.7 % more
/// instructions per frame in the AVX2 one.)
#[inline(always)]
pub(crate) fn mask_of<const N: usize>(v: &[u32; N]) -> u32 {
    v.iter()
        .enumerate()
        .fold(0, |m, (l, &x)| m | ((x != 0) as u32) << l)
}

/// The lanes set in `mask`, lowest first: one step per set bit (a loop
/// over all lanes testing each bit mispredicts the test).
#[inline(always)]
pub(crate) fn lanes_of(mask: u32) -> impl Iterator<Item = usize> {
    let mut m = mask;
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let l = m.trailing_zeros() as usize;
            m &= m - 1;
            l
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every operation gives the same lanes in both instruction sets, and
    /// what it is documented to give.
    #[test]
    fn avx2_agrees_with_portable() {
        let table: [f32; LANES] = std::array::from_fn(|i| i as f32 * 1.5 - 2.0);
        let index = [7, 0, 3, 3, 9, 1, 2, 15];
        let splats: Vec<[f32; LANES]> = (0..=LANES)
            .map(|from| std::array::from_fn(|l| if l >= from { 9.5 } else { table[l] }))
            .collect();
        for (from, want) in splats.iter().enumerate() {
            assert_eq!(Portable.splat_from(table, 9.5, from), *want);
        }
        let long: Vec<f32> = (0..20).map(|i| i as f32).collect();
        let gathered = [7.0, 0.0, 3.0, 3.0, 9.0, 1.0, 2.0, 15.0];
        assert_eq!(Portable.gather(&long, &index), gathered);
        let clamped = [0u32, 25, u32::MAX, 19, 4, 5, 6, 7];
        assert_eq!(
            Portable.gather(&long, &clamped),
            [0.0, 19.0, 19.0, 19.0, 4.0, 5.0, 6.0, 7.0]
        );
        let v = [0, 1, 0, 5, 0, 0, u32::MAX, 0];
        assert_eq!(Portable.nonzero_mask(&v), 0b0100_1010);
        #[cfg(target_arch = "x86_64")]
        if let Some(avx2) = Avx2::detect() {
            for (from, want) in splats.iter().enumerate() {
                assert_eq!(avx2.splat_from(table, 9.5, from), *want);
            }
            assert_eq!(avx2.gather(&long, &index), gathered);
            assert_eq!(
                avx2.gather(&long, &clamped),
                Portable.gather(&long, &clamped)
            );
            assert_eq!(avx2.nonzero_mask(&v), 0b0100_1010);
        }
    }

    /// A wide kernel: lane-wise arithmetic over 16 lanes and a lane mask.
    struct Wide<'a>(&'a [f32; 16]);

    impl Kernel for Wide<'_> {
        type Output = ([f32; 16], u32);
        const WIDE: bool = true;

        #[inline(always)]
        fn run<I: Isa>(self, isa: I) -> Self::Output {
            let x = self.0;
            let y: [f32; 16] = std::array::from_fn(|l| (x[l] * 1.7 + 0.3) / (x[l] * x[l] + 1.0));
            let big: [u32; 16] = std::array::from_fn(|l| (y[l] > 0.5) as u32);
            let (lo, hi) = big.split_at(LANES);
            let mask = isa.nonzero_mask(lo.try_into().unwrap())
                | isa.nonzero_mask(hi.try_into().unwrap()) << LANES;
            (y, mask)
        }
    }

    /// A [`Kernel::WIDE`] loop gives the portable copy's bits in whichever
    /// copy `dispatch` runs it (the AVX-512 one on a CPU that has it).
    #[test]
    fn wide_kernels_agree_with_portable() {
        let x: [f32; 16] = std::array::from_fn(|l| l as f32 * 0.37 - 2.5);
        let (y, mask) = dispatch(Wide(&x));
        let (py, pmask) = Wide(&x).run(Portable);
        assert_eq!(y.map(f32::to_bits), py.map(f32::to_bits));
        assert_eq!(mask, pmask);
        assert!(mask != 0 && mask != 0xffff, "{mask:#x}");
    }
}
