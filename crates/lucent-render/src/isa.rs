//! The render loop compiled a second time for AVX2: the one module of this
//! crate with `unsafe` code.
//!
//! The crate is built for baseline x86-64 (SSE2: sixteen vector registers,
//! two-operand instructions), so one binary runs on any x86-64 and the
//! workspace builds on other architectures. [`Isa::detect`] checks at run
//! time for AVX2, FMA, BMI1, BMI2, LZCNT and POPCNT; where they are present,
//! [`Isa::run`] runs a [`Kernel`] (the samples of one image row) inside one
//! function compiled with those features. Everything the kernel calls that
//! is inlined into it (the sample keying and camera ray, the path tracer's
//! loop and, inlined there, surface interaction, BSDF and light sampling,
//! random numbers) is then a second copy in three-operand VEX code, with
//! fewer spills; what stays out of line (the traversal, which picks its own
//! AVX2 kernel in `lucent-accel`, and the few functions marked
//! `#[inline(never)]`) runs its usual copy.
//!
//! Both copies round identically: Rust never contracts a multiply and an
//! add into a fused multiply-add, nor reorders floating-point operations,
//! whatever the target features, so the AVX2 copy makes the very same bytes
//! (`render::tests` renders through both and compares the films bit for
//! bit). Elsewhere than x86-64, and on an x86-64 without those features,
//! [`Isa::run`] runs the kernel as it is compiled: that copy is the
//! reference.
//!
//! `unsafe` here: the one call of the `#[target_feature]` function, sound
//! because an [`Isa`] whose `avx2` is set exists only once [`Isa::detect`]
//! found every feature it enables.
#![allow(unsafe_code, reason = "the AVX2 copy of the render loop; see the module docs")]

/// Work that [`Isa::run`] runs in the copy the processor supports: the
/// samples of one image row. `run` must be `#[inline(always)]`, and so must
/// every function of this crate it reaches that should be part of the AVX2
/// copy: LLVM inlines a function into the AVX2 entry only when told to
/// (closures are not, which is why a kernel is a trait).
pub(crate) trait Kernel {
    /// What the work returns.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// The instruction set the render loop runs in: baseline, or the AVX2 copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Isa {
    /// The processor has every feature `run_avx2` is compiled with (never
    /// off x86-64, where nothing reads it).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "no AVX2 copy off x86-64"))]
    avx2: bool,
}

impl Isa {
    /// The best copy this processor runs.
    pub(crate) fn detect() -> Self {
        Self { avx2: avx2_present() }
    }

    /// The baseline copy, whatever the processor (the reference).
    #[cfg(test)]
    pub(crate) fn baseline() -> Self {
        Self { avx2: false }
    }

    /// Whether [`Isa::run`] takes the AVX2 copy.
    #[cfg(all(test, target_arch = "x86_64"))]
    pub(crate) fn is_avx2(self) -> bool {
        self.avx2
    }

    /// Runs `kernel` in the copy this value names.
    #[inline(always)]
    pub(crate) fn run<K: Kernel>(self, kernel: K) -> K::Output {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only by `detect`, once
            // `avx2_present` found every feature `run_avx2` enables.
            return unsafe { run_avx2(kernel) };
        }
        kernel.run()
    }
}

/// Whether this processor has every feature [`run_avx2`] is compiled with.
#[cfg(target_arch = "x86_64")]
fn avx2_present() -> bool {
    use std::arch::is_x86_feature_detected as has;
    has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt") && has!("popcnt")
}

/// No AVX2 copy off x86-64.
#[cfg(not(target_arch = "x86_64"))]
fn avx2_present() -> bool {
    false
}

/// `kernel` compiled for AVX2 and its companions: its `run` and what that
/// inlines become this function's body.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
}
