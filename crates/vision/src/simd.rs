//! Run-time choice of a wider instruction set for the hot kernels, with one portable body.
//!
//! slamkit builds for the baseline x86-64 target (SSE2), which lacks a 32-bit vector multiply
//! (`pmulld`, SSE4.1), byte shuffles (`pshufb`, SSSE3) and 256-bit registers: loops over `u32`
//! products then fall back to pairs of `pmuludq` and shuffles. OpenCV picks AVX2 code at run
//! time; so does [`dispatch_avx2!`]: it compiles the same portable body a second time with
//! `#[target_feature(enable = "avx2")]` and calls that copy when `is_x86_feature_detected!`
//! reports AVX2. Other targets (ARM on small robots) and older x86 CPUs run the portable body,
//! which is plain safe Rust that the compiler vectorises for whatever the target has. Both
//! copies compute in integers (or the same IEEE `f32` operations, no fused multiply–add), so
//! their results are identical; each kernel's tests check the two against each other.

/// Defines a kernel once and compiles it twice: `$vis fn $name<T: Bound>(args) -> ret`
/// (generics and return type optional) runs the body compiled for AVX2 when the CPU has it, and
/// the portable copy, the `#[inline(always)]` fn `$portable` with the same signature, otherwise.
/// The body's own helpers should be `#[inline(always)]` too, so that all of its loops are
/// compiled inside the AVX2 copy. Arguments are plain names (destructure them in the body), as
/// the dispatcher passes them on; tests compare `$portable` with `$name` and with references.
///
/// ```text
/// dispatch_avx2! {
///     /// What the kernel computes.
///     pub fn kernel(img: &GrayImage, k: &[u16]) -> GrayImage;
///     /// How the portable body computes it.
///     portable kernel_portable {
///         separable(img, k)
///     }
/// }
/// ```
macro_rules! dispatch_avx2 {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident $(<$($gen:ident : $bound:path),+>)?
            ( $($arg:ident : $ty:ty),* $(,)? ) $(-> $ret:ty)?;
        $(#[$body_attr:meta])*
        portable $portable:ident $body:block
    ) => {
        $(#[$attr])*
        $vis fn $name $(<$($gen: $bound),+>)? ($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                /// The portable body compiled with AVX2 enabled.
                #[target_feature(enable = "avx2")]
                fn with_avx2 $(<$($gen: $bound),+>)? ($($arg: $ty),*) $(-> $ret)? {
                    $portable($($arg),*)
                }
                // SAFETY: the CPU supports AVX2, the only feature `with_avx2` enables.
                #[allow(unsafe_code)]
                return unsafe { with_avx2($($arg),*) };
            }
            $portable($($arg),*)
        }

        $(#[$body_attr])*
        #[inline(always)]
        fn $portable $(<$($gen: $bound),+>)? ($($arg: $ty),*) $(-> $ret)? $body
    };
}

pub(crate) use dispatch_avx2;
