//! Batches: one joint evaluated at many independent states.
//!
//! Three ways to run [`Joint::evaluate`] over a slice of states, all writing into
//! a caller-provided output slice (no allocation) and returning a [`BatchError`]
//! instead of panicking when the slices disagree:
//!
//! - [`evaluate_batch`]: one state after the other, any scalar. Given a joint
//!   instantiated at a SIMD lane type and states already packed into lanes
//!   (structure of arrays), it is also the fastest SIMD path.
//! - `evaluate_batch_simd` (feature `simd`): scalar states in, scalar
//!   evaluations out, evaluated 4 (`f64` in [`WideF64x4`]) or 8 (`f32` in
//!   [`WideF32x8`]) at a time by a joint instantiated at the lane type. The
//!   generated code is generic over `T: SimdRealField + Copy`, so the same code
//!   runs on the lanes; [`Lanes`] packs states into lanes and unpacks the
//!   results, [`splat`] builds a joint's lane parameters from scalar ones.
//!   Packing costs: a universal joint in `omega_body` reads 26 numbers per state
//!   and writes 56, and moving them between scalar and lane layout takes about
//!   as long as the evaluation itself (about 15 ns per state on the default
//!   x86-64 target). It pays with `f32 × 8` (1.3× the scalar `f64` rate, 1.5×
//!   the scalar `f32` rate) and with AVX (`f64 × 4`: 1.2×), not with `f64 × 4`
//!   on SSE2 only (0.86×); states kept in lanes avoid it (`report/batches.md`).
//! - `evaluate_batch_par` and `evaluate_batch_simd_par` (feature `parallel`,
//!   and `simd` for the second): the same over chunks of the batch on rayon's
//!   thread pool (run them inside `ThreadPool::install` to choose the threads).
//!
//! Each lane of a SIMD result equals the scalar result bitwise, except for the
//! `sin`/`cos` of a `rotational_driver` (or of user-written rows): `wide`'s
//! vectorised `sin`/`cos` is a different polynomial from the scalar one and may
//! differ in the last bit or two.
//!
//! # Time in a lane pack
//!
//! The state types hold the time as one `f64` (a driven joint's generated code
//! calls `TimeFunction::eval(state.t)` in `f64`), so the states in one lane pack
//! must share `t`. [`Lanes::pack`] checks this and returns [`MixedTimes`] rather
//! than packing silently at the first lane's time. The SIMD batch functions never
//! give a wrong result either: a pack whose states have different times is
//! evaluated one state at a time (each state splatted over all lanes), which is
//! correct but as slow as the scalar path, and is counted in
//! [`LaneReport::split`]. For full speed, keep equal times together: a batch at
//! one instant, or sorted by time. A joint that does not read the time (not
//! driven) gives the same result for any `t`; give its states the same `t` (the
//! constructors `TwoBodies::new`, `OneBody::new` use 0).

use core::fmt;

use crate::{Evaluation, Joint};

/// Why a batch was not evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum BatchError {
    /// The state and output slices have different lengths. Nothing was written.
    LengthMismatch {
        /// Number of states.
        states: usize,
        /// Length of the output slice.
        outputs: usize,
    },
}

impl fmt::Display for BatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BatchError::LengthMismatch { states, outputs } => {
                write!(f, "batch of {states} states but {outputs} output slots; nothing was evaluated")
            }
        }
    }
}

impl core::error::Error for BatchError {}

fn check_lengths(states: usize, outputs: usize) -> Result<(), BatchError> {
    if states == outputs { Ok(()) } else { Err(BatchError::LengthMismatch { states, outputs }) }
}

/// Evaluates `joint` at every state: `out[i] = joint.evaluate(&states[i])`.
///
/// Works for any scalar the joint is instantiated at. With a joint at a lane type
/// (`Cardan<WideF64x4>`) and states already packed into lanes, each call
/// evaluates 4 or 8 states: the structure-of-arrays path, with no packing cost.
///
/// # Errors
///
/// [`BatchError::LengthMismatch`] if `states.len() != out.len()`; nothing is
/// written then.
///
/// # Example
///
/// ```
/// use joint_runtime::batch::{BatchError, evaluate_batch};
/// use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
/// use joint_runtime::{Evaluation, Joint, OmegaBody, TwoBodies};
///
/// #[derive(Joint)]
/// #[joint(universal, formulation = omega_body, s = [0, 1, 0], h = [0, 0, 1])]
/// struct Cardan<T> { rho1: Vector3<T>, rho2: Vector3<T> }
///
/// let joint = Cardan { rho1: Vector3::new(0.5, 0.0, 0.0), rho2: Vector3::new(-0.5, 0.0, 0.0) };
/// let states: Vec<_> = (0..10)
///     .map(|i| {
///         let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.1 * i as f64);
///         let body = |r| OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::new(10.0, 0.0, 0.0));
///         TwoBodies::new(body(Vector3::zeros()), body(Vector3::x()))
///     })
///     .collect();
/// let mut out = vec![joint.evaluate(&states[0]); states.len()];
/// evaluate_batch(&joint, &states, &mut out)?;
/// assert_eq!(out[7], joint.evaluate(&states[7]));
/// let too_short = evaluate_batch(&joint, &states, &mut out[..3]);
/// assert_eq!(too_short, Err(BatchError::LengthMismatch { states: 10, outputs: 3 }));
/// # Ok::<(), BatchError>(())
/// ```
pub fn evaluate_batch<J, T, const R: usize, const C: usize>(
    joint: &J,
    states: &[J::State],
    out: &mut [Evaluation<T, R, C>],
) -> Result<(), BatchError>
where
    J: Joint<T, R, C> + ?Sized,
{
    check_lengths(states.len(), out.len())?;
    evaluate_each(joint, states, out);
    Ok(())
}

fn evaluate_each<J, T, const R: usize, const C: usize>(joint: &J, states: &[J::State], out: &mut [Evaluation<T, R, C>])
where
    J: Joint<T, R, C> + ?Sized,
{
    for (state, slot) in states.iter().zip(out.iter_mut()) {
        *slot = joint.evaluate(state);
    }
}

/// Number of states each rayon task evaluates (a multiple of every lane width, so
/// only the last task pads a lane pack).
#[cfg(feature = "parallel")]
pub const PARALLEL_CHUNK: usize = 2048;

/// [`evaluate_batch`] over chunks of [`PARALLEL_CHUNK`] states on rayon's thread
/// pool (feature `parallel`). The results are those of [`evaluate_batch`], bitwise.
///
/// # Errors
///
/// [`BatchError::LengthMismatch`] if `states.len() != out.len()`; nothing is
/// written then.
///
/// # Example
///
/// ```
/// use joint_runtime::batch::evaluate_batch_par;
/// use joint_runtime::nalgebra::{Vector3, Vector4};
/// use joint_runtime::{Evaluation, Joint, RelativeState};
///
/// #[derive(Joint)]
/// #[joint(spherical, formulation = relative_b2)]
/// struct Ball<T> { rho1: Vector3<T>, rho2: Vector3<T> }
///
/// let joint = Ball { rho1: Vector3::new(0.0, 0.0, 1.0), rho2: Vector3::zeros() };
/// let state = |i: usize| RelativeState {
///     delta: Vector3::new(i as f64, 0.0, 0.0),
///     p: Vector4::new(1.0, 0.0, 0.0, 0.0),
///     delta_dot: Vector3::zeros(),
///     omega: Vector3::zeros(),
///     t: 0.0,
/// };
/// let states: Vec<_> = (0..5000).map(state).collect();
/// let mut out = vec![joint.evaluate(&states[0]); states.len()];
/// evaluate_batch_par(&joint, &states, &mut out)?;
/// assert_eq!(out[4321], joint.evaluate(&states[4321]));
/// # Ok::<(), joint_runtime::batch::BatchError>(())
/// ```
#[cfg(feature = "parallel")]
pub fn evaluate_batch_par<J, T, const R: usize, const C: usize>(
    joint: &J,
    states: &[J::State],
    out: &mut [Evaluation<T, R, C>],
) -> Result<(), BatchError>
where
    J: Joint<T, R, C> + Sync + ?Sized,
    J::State: Sync,
    T: Send,
{
    use rayon::prelude::*;
    check_lengths(states.len(), out.len())?;
    states
        .par_chunks(PARALLEL_CHUNK)
        .zip(out.par_chunks_mut(PARALLEL_CHUNK))
        .for_each(|(states, out)| evaluate_each(joint, states, out));
    Ok(())
}

#[cfg(feature = "simd")]
pub use simba::simd::{WideF32x8, WideF64x4};
#[cfg(feature = "simd")]
pub use simd::{LaneReport, LaneScalar, Lanes, MixedTimes, evaluate_batch_simd, splat};

#[cfg(all(feature = "simd", feature = "parallel"))]
pub use simd::evaluate_batch_simd_par;

#[cfg(feature = "simd")]
mod simd {
    use core::fmt;

    use nalgebra::{ArrayStorage, RealField, SMatrix, SimdRealField};
    use simba::simd::{WideF32x8, WideF64x4};

    use super::{BatchError, check_lengths};
    use crate::{AxisFrame, EulerBody, Evaluation, Joint, OmegaBody, OneBody, RelativeState, TwoBodies};

    /// A scalar with a SIMD type of `N` lanes (feature `simd`): `f64` in
    /// [`WideF64x4`], `f32` in [`WideF32x8`].
    ///
    /// ```
    /// use joint_runtime::batch::{LaneScalar, WideF64x4};
    ///
    /// let w: WideF64x4 = f64::pack([1.0, 2.0, 3.0, 4.0]);
    /// assert_eq!(f64::unpack(w * w), [1.0, 4.0, 9.0, 16.0]);
    /// ```
    pub trait LaneScalar<const N: usize>: RealField + Copy {
        /// The SIMD type holding `N` values, on which generated code runs.
        type Wide: SimdRealField<Element = Self> + Copy;
        /// `N` values into one SIMD value, lane `i` from `lanes[i]`.
        fn pack(lanes: [Self; N]) -> Self::Wide;
        /// The `N` lanes of a SIMD value.
        fn unpack(wide: Self::Wide) -> [Self; N];
    }

    impl LaneScalar<4> for f64 {
        type Wide = WideF64x4;
        #[inline(always)]
        fn pack(lanes: [f64; 4]) -> WideF64x4 {
            WideF64x4::from_arr(lanes)
        }
        #[inline(always)]
        fn unpack(wide: WideF64x4) -> [f64; 4] {
            wide.into_arr()
        }
    }

    impl LaneScalar<8> for f32 {
        type Wide = WideF32x8;
        #[inline(always)]
        fn pack(lanes: [f32; 8]) -> WideF32x8 {
            WideF32x8::from_arr(lanes)
        }
        #[inline(always)]
        fn unpack(wide: WideF32x8) -> [f32; 8] {
            wide.into_arr()
        }
    }

    /// States at different times in one lane pack (feature `simd`): the time is one
    /// `f64` shared by all lanes (a driven joint evaluates its time function once).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct MixedTimes {
        /// The first lane whose time differs from lane 0's.
        pub lane: usize,
        /// Lane 0's time.
        pub expected: f64,
        /// That lane's time.
        pub found: f64,
    }

    impl fmt::Display for MixedTimes {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(
                f,
                "lane {} is at t = {} but lane 0 at t = {}: the states of one lane pack must share their time",
                self.lane, self.found, self.expected
            )
        }
    }

    impl core::error::Error for MixedTimes {}

    /// A value with a lane version of `N` lanes (feature `simd`): `N` states in,
    /// one state of SIMD scalars out (array of structures to structure of arrays),
    /// and back.
    ///
    /// Implemented for `SMatrix<f64, R, C>` (so `Vector3`, `Vector4`),
    /// [`OmegaBody`], [`EulerBody`], [`TwoBodies`], [`OneBody`],
    /// [`RelativeState`], [`AxisFrame`] and [`Evaluation`], with `f64` in 4 lanes
    /// and `f32` in 8. The time of [`TwoBodies`], [`OneBody`] and [`RelativeState`]
    /// stays one `f64`: [`Lanes::pack`] requires it bitwise equal in all lanes.
    ///
    /// ```
    /// use joint_runtime::batch::{Lanes, MixedTimes, WideF64x4};
    /// use joint_runtime::nalgebra::{Vector3, Vector4};
    /// use joint_runtime::{OmegaBody, OneBody};
    ///
    /// let body = |x: f64| OmegaBody {
    ///     r: Vector3::new(x, 0.0, 0.0),
    ///     p: Vector4::new(1.0, 0.0, 0.0, 0.0),
    ///     rdot: Vector3::zeros(),
    ///     omega: Vector3::zeros(),
    /// };
    /// let states = [0.0, 1.0, 2.0, 3.0].map(|x| OneBody { body: body(x), t: 0.5 });
    /// let packed: OneBody<OmegaBody<WideF64x4>> = Lanes::pack(&states)?;
    /// assert_eq!(packed.body.r.x.into_arr(), [0.0, 1.0, 2.0, 3.0]);
    /// assert_eq!(<OneBody<OmegaBody<f64>> as Lanes<4>>::unpack(&packed), states);
    ///
    /// let mut late = states;
    /// late[3].t = 0.6;
    /// let mixed = <OneBody<OmegaBody<f64>> as Lanes<4>>::pack(&late);
    /// assert_eq!(mixed.err(), Some(MixedTimes { lane: 3, expected: 0.5, found: 0.6 }));
    /// # Ok::<(), MixedTimes>(())
    /// ```
    pub trait Lanes<const N: usize>: Copy {
        /// The same structure over the SIMD scalar (`OmegaBody<WideF64x4>` for `OmegaBody<f64>`).
        type Packed: Copy;
        /// Lane `i` from `lanes[i]`.
        ///
        /// # Errors
        ///
        /// [`MixedTimes`] if the states' times are not bitwise equal.
        fn pack(lanes: &[Self; N]) -> Result<Self::Packed, MixedTimes> {
            Self::gather(lanes, |s| s)
        }
        /// Lane `i` from `get(&lanes[i])`: packs a part of each of `N` larger
        /// values in place (a body of each of `N` two-body states), without first
        /// copying the parts out.
        ///
        /// # Errors
        ///
        /// [`MixedTimes`] if the parts' times are not bitwise equal.
        fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes>;
        /// `self` in every lane (never fails: the times agree).
        fn splat(&self) -> Self::Packed;
        /// The `N` lanes, lane `i` in element `i`.
        fn unpack(packed: &Self::Packed) -> [Self; N];
    }

    /// A matrix (or vector) of scalars in every lane: the parameters of a joint at
    /// the lane type from the scalar ones (feature `simd`).
    ///
    /// ```
    /// use joint_runtime::batch::{WideF64x4, splat};
    /// use joint_runtime::nalgebra::Vector3;
    ///
    /// let rho: Vector3<WideF64x4> = splat(&Vector3::new(0.5, 0.0, 0.0));
    /// assert_eq!(rho.x.into_arr(), [0.5; 4]);
    /// ```
    #[inline]
    pub fn splat<E, const N: usize, const R: usize, const C: usize>(m: &SMatrix<E, R, C>) -> SMatrix<E::Wide, R, C>
    where
        E: LaneScalar<N>,
    {
        <SMatrix<E, R, C> as Lanes<N>>::splat(m)
    }

    // The gathers and scatters below are plain loops with constant trip counts
    // on purpose: `array::map`/`from_fn` chains were not inlined (`try_map` stayed
    // a call per entry) and the optimiser turned the rest into AVX-512 gathers,
    // together 3× slower than the generated code itself.
    #[inline(always)]
    fn pack_field<S, E, const N: usize, const R: usize, const C: usize>(
        lanes: &[S; N],
        field: impl Fn(&S) -> &SMatrix<E, R, C>,
    ) -> SMatrix<E::Wide, R, C>
    where
        E: LaneScalar<N>,
    {
        SMatrix::from_fn(|r, c| {
            let mut values = [field(&lanes[0])[(r, c)]; N];
            for (value, lane) in values.iter_mut().zip(lanes) {
                *value = field(lane)[(r, c)];
            }
            E::pack(values)
        })
    }

    /// Lane `l` of `m` into `field(&mut slots[l])`, for every lane a slot exists for.
    #[inline(always)]
    fn unpack_into<E, X, const N: usize, const R: usize, const C: usize>(
        m: &SMatrix<E::Wide, R, C>,
        slots: &mut [X],
        field: impl Fn(&mut X) -> &mut SMatrix<E, R, C>,
    ) where
        E: LaneScalar<N>,
    {
        for c in 0..C {
            for r in 0..R {
                for (slot, value) in slots.iter_mut().zip(E::unpack(m[(r, c)])) {
                    field(slot)[(r, c)] = value;
                }
            }
        }
    }

    #[inline(always)]
    fn splat_matrix<E, const N: usize, const R: usize, const C: usize>(m: &SMatrix<E, R, C>) -> SMatrix<E::Wide, R, C>
    where
        E: LaneScalar<N>,
    {
        SMatrix::from_data(ArrayStorage(m.data.0.map(|column| column.map(|x| E::pack([x; N])))))
    }

    #[inline(always)]
    fn unpack_matrix<E, const N: usize, const R: usize, const C: usize>(
        m: &SMatrix<E::Wide, R, C>,
    ) -> [SMatrix<E, R, C>; N]
    where
        E: LaneScalar<N>,
    {
        let mut lanes = [SMatrix::zeros(); N];
        unpack_into::<E, _, N, R, C>(m, &mut lanes, |x| x);
        lanes
    }

    fn common_time<S, const N: usize>(lanes: &[S; N], time: impl Fn(&S) -> f64) -> Result<f64, MixedTimes> {
        let expected = lanes.first().map_or(0.0, &time);
        for (lane, state) in lanes.iter().enumerate() {
            let found = time(state);
            if found.to_bits() != expected.to_bits() {
                return Err(MixedTimes { lane, expected, found });
            }
        }
        Ok(expected)
    }

    impl<E, const N: usize, const R: usize, const C: usize> Lanes<N> for SMatrix<E, R, C>
    where
        E: LaneScalar<N>,
    {
        type Packed = SMatrix<E::Wide, R, C>;
        #[inline]
        fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes> {
            Ok(pack_field(lanes, get))
        }
        #[inline]
        fn splat(&self) -> Self::Packed {
            splat_matrix(self)
        }
        #[inline]
        fn unpack(packed: &Self::Packed) -> [Self; N] {
            unpack_matrix(packed)
        }
    }

    /// Lanes of a struct whose fields are all matrices of `E`.
    macro_rules! matrix_struct_lanes {
        ($name:ident { $($field:ident),* }) => {
            impl<E, const N: usize> Lanes<N> for $name<E>
            where
                E: LaneScalar<N>,
            {
                type Packed = $name<E::Wide>;
                #[inline]
                fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes> {
                    Ok($name { $($field: pack_field(lanes, |s| &get(s).$field)),* })
                }
                #[inline]
                fn splat(&self) -> Self::Packed {
                    $name { $($field: splat_matrix(&self.$field)),* }
                }
                #[inline]
                fn unpack(packed: &Self::Packed) -> [Self; N] {
                    $(let $field = unpack_matrix::<E, N, _, _>(&packed.$field);)*
                    core::array::from_fn(|l| $name { $($field: $field[l]),* })
                }
            }
        };
    }

    matrix_struct_lanes!(OmegaBody { r, p, rdot, omega });
    matrix_struct_lanes!(EulerBody { r, p, rdot, pdot });
    matrix_struct_lanes!(AxisFrame { axis, b, c });

    impl<E, const N: usize> Lanes<N> for RelativeState<E>
    where
        E: LaneScalar<N>,
    {
        type Packed = RelativeState<E::Wide>;
        #[inline]
        fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes> {
            Ok(RelativeState {
                t: common_time(lanes, |s| get(s).t)?,
                delta: pack_field(lanes, |s| &get(s).delta),
                p: pack_field(lanes, |s| &get(s).p),
                delta_dot: pack_field(lanes, |s| &get(s).delta_dot),
                omega: pack_field(lanes, |s| &get(s).omega),
            })
        }
        #[inline]
        fn splat(&self) -> Self::Packed {
            RelativeState {
                delta: splat_matrix(&self.delta),
                p: splat_matrix(&self.p),
                delta_dot: splat_matrix(&self.delta_dot),
                omega: splat_matrix(&self.omega),
                t: self.t,
            }
        }
        #[inline]
        fn unpack(packed: &Self::Packed) -> [Self; N] {
            let delta = unpack_matrix::<E, N, _, _>(&packed.delta);
            let p = unpack_matrix::<E, N, _, _>(&packed.p);
            let delta_dot = unpack_matrix::<E, N, _, _>(&packed.delta_dot);
            let omega = unpack_matrix::<E, N, _, _>(&packed.omega);
            core::array::from_fn(|l| RelativeState {
                delta: delta[l],
                p: p[l],
                delta_dot: delta_dot[l],
                omega: omega[l],
                t: packed.t,
            })
        }
    }

    impl<B: Lanes<N>, const N: usize> Lanes<N> for TwoBodies<B> {
        type Packed = TwoBodies<B::Packed>;
        #[inline]
        fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes> {
            Ok(TwoBodies {
                t: common_time(lanes, |s| get(s).t)?,
                body1: B::gather(lanes, |s| &get(s).body1)?,
                body2: B::gather(lanes, |s| &get(s).body2)?,
            })
        }
        #[inline]
        fn splat(&self) -> Self::Packed {
            TwoBodies { body1: self.body1.splat(), body2: self.body2.splat(), t: self.t }
        }
        #[inline]
        fn unpack(packed: &Self::Packed) -> [Self; N] {
            let body1 = B::unpack(&packed.body1);
            let body2 = B::unpack(&packed.body2);
            core::array::from_fn(|l| TwoBodies { body1: body1[l], body2: body2[l], t: packed.t })
        }
    }

    impl<B: Lanes<N>, const N: usize> Lanes<N> for OneBody<B> {
        type Packed = OneBody<B::Packed>;
        #[inline]
        fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes> {
            Ok(OneBody { t: common_time(lanes, |s| get(s).t)?, body: B::gather(lanes, |s| &get(s).body)? })
        }
        #[inline]
        fn splat(&self) -> Self::Packed {
            OneBody { body: self.body.splat(), t: self.t }
        }
        #[inline]
        fn unpack(packed: &Self::Packed) -> [Self; N] {
            let body = B::unpack(&packed.body);
            core::array::from_fn(|l| OneBody { body: body[l], t: packed.t })
        }
    }

    impl<E, const N: usize, const R: usize, const C: usize> Lanes<N> for Evaluation<E, R, C>
    where
        E: LaneScalar<N>,
    {
        type Packed = Evaluation<E::Wide, R, C>;
        #[inline]
        fn gather<S>(lanes: &[S; N], get: impl Fn(&S) -> &Self) -> Result<Self::Packed, MixedTimes> {
            Ok(Evaluation {
                phi: pack_field(lanes, |e| &get(e).phi),
                jacobian: pack_field(lanes, |e| &get(e).jacobian),
                gamma: pack_field(lanes, |e| &get(e).gamma),
            })
        }
        #[inline]
        fn splat(&self) -> Self::Packed {
            Evaluation {
                phi: splat_matrix(&self.phi),
                jacobian: splat_matrix(&self.jacobian),
                gamma: splat_matrix(&self.gamma),
            }
        }
        #[inline]
        fn unpack(packed: &Self::Packed) -> [Self; N] {
            let zero = Evaluation { phi: SMatrix::zeros(), jacobian: SMatrix::zeros(), gamma: SMatrix::zeros() };
            let mut lanes = [zero; N];
            unpack_evaluation::<E, N, R, C>(packed, &mut lanes);
            lanes
        }
    }

    /// How a SIMD batch was evaluated (feature `simd`).
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
    #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
    #[non_exhaustive]
    pub struct LaneReport {
        /// Lane packs evaluated at full width (one generated call each), the padded
        /// last one included.
        pub packed: usize,
        /// Lane packs whose states had different times, evaluated one state at a
        /// time (each splatted over all lanes): correct, at the scalar speed.
        pub split: usize,
        /// Unused lanes in the last pack (copies of a state of the batch, discarded).
        pub padding: usize,
    }

    impl core::ops::Add for LaneReport {
        type Output = LaneReport;
        fn add(self, other: LaneReport) -> LaneReport {
            LaneReport {
                packed: self.packed + other.packed,
                split: self.split + other.split,
                padding: self.padding + other.padding,
            }
        }
    }

    #[inline(always)]
    fn evaluate_pack<J, E, S, const N: usize, const R: usize, const C: usize>(
        joint: &J,
        lanes: &[S; N],
        out: &mut [Evaluation<E, R, C>],
        report: &mut LaneReport,
    ) where
        E: LaneScalar<N>,
        S: Lanes<N>,
        J: Joint<E::Wide, R, C, State = S::Packed> + ?Sized,
    {
        match S::pack(lanes) {
            Ok(packed) => {
                unpack_evaluation(&joint.evaluate(&packed), out);
                report.packed += 1;
            }
            Err(_) => {
                // Each state alone, splatted over all lanes: lane 0 is its result.
                for (slot, state) in out.iter_mut().zip(lanes) {
                    unpack_evaluation(&joint.evaluate(&state.splat()), core::slice::from_mut(slot));
                }
                report.split += 1;
            }
        }
    }

    /// Lane `l` of `e` into `out[l]`, for the lanes `out` has slots for.
    ///
    /// Scattered straight into `out`: through a buffer on the stack was 20 %
    /// slower for a cache-resident batch (1.5× faster for one far larger than
    /// the cache), lane by lane 70 % slower.
    #[inline(always)]
    fn unpack_evaluation<E, const N: usize, const R: usize, const C: usize>(
        e: &Evaluation<E::Wide, R, C>,
        out: &mut [Evaluation<E, R, C>],
    ) where
        E: LaneScalar<N>,
    {
        unpack_into::<E, _, N, R, 1>(&e.phi, out, |x| &mut x.phi);
        unpack_into::<E, _, N, R, C>(&e.jacobian, out, |x| &mut x.jacobian);
        unpack_into::<E, _, N, R, 1>(&e.gamma, out, |x| &mut x.gamma);
    }

    fn evaluate_lanes<J, E, S, const N: usize, const R: usize, const C: usize>(
        joint: &J,
        states: &[S],
        out: &mut [Evaluation<E, R, C>],
    ) -> LaneReport
    where
        E: LaneScalar<N>,
        S: Lanes<N>,
        J: Joint<E::Wide, R, C, State = S::Packed> + ?Sized,
    {
        let mut report = LaneReport::default();
        let (packs, rest) = states.as_chunks::<N>();
        let (slots, rest_slots) = out.as_chunks_mut::<N>();
        for (lanes, slots) in packs.iter().zip(slots.iter_mut()) {
            evaluate_pack(joint, lanes, slots, &mut report);
        }
        if let Some(&first) = rest.first() {
            let mut lanes = [first; N];
            for (lane, state) in lanes.iter_mut().zip(rest) {
                *lane = *state;
            }
            evaluate_pack(joint, &lanes, rest_slots, &mut report);
            report.padding += N - rest.len();
        }
        report
    }

    /// Evaluates `joint` (instantiated at the lane type) at every scalar state,
    /// `N` states per generated call (feature `simd`): `f64` states 4 at a time in
    /// [`WideF64x4`], `f32` states 8 at a time in [`WideF32x8`].
    ///
    /// Consecutive states form a lane pack; the last pack is padded with copies of
    /// one of its states. A pack whose states have different times is evaluated
    /// one state at a time (see [the module docs](crate::batch)); the [`LaneReport`] says
    /// how often. Build the lane joint with [`splat`] (or [`Lanes::splat`]) of the
    /// scalar joint's parameters, or with different parameters per lane via
    /// [`Lanes::pack`].
    ///
    /// # Errors
    ///
    /// [`BatchError::LengthMismatch`] if `states.len() != out.len()`; nothing is
    /// written then.
    ///
    /// # Example
    ///
    /// ```
    /// use joint_runtime::batch::{LaneReport, WideF64x4, evaluate_batch_simd, splat};
    /// use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
    /// use joint_runtime::{Evaluation, Joint, OmegaBody, TwoBodies};
    ///
    /// #[derive(Joint)]
    /// #[joint(universal, formulation = omega_body)]
    /// struct Cardan<T> { s: Vector3<T>, h: Vector3<T>, rho1: Vector3<T>, rho2: Vector3<T> }
    ///
    /// let joint = Cardan { s: Vector3::y(), h: Vector3::z(), rho1: Vector3::x() * 0.5, rho2: Vector3::x() * -0.5 };
    /// let wide: Cardan<WideF64x4> =
    ///     Cardan { s: splat(&joint.s), h: splat(&joint.h), rho1: splat(&joint.rho1), rho2: splat(&joint.rho2) };
    /// let states: Vec<_> = (0..10)
    ///     .map(|i| {
    ///         let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.1 * i as f64);
    ///         let body = |r| OmegaBody::from_rotation(r, &q, Vector3::zeros(), Vector3::new(10.0, 0.0, 0.0));
    ///         TwoBodies::new(body(Vector3::zeros()), body(Vector3::x()))
    ///     })
    ///     .collect();
    /// let mut out = vec![joint.evaluate(&states[0]); states.len()];
    /// let report = evaluate_batch_simd(&wide, &states, &mut out)?;
    /// assert_eq!((report.packed, report.split, report.padding), (3, 0, 2));
    /// for (state, e) in states.iter().zip(&out) {
    ///     assert_eq!(*e, joint.evaluate(state)); // bitwise
    /// }
    /// # Ok::<(), joint_runtime::batch::BatchError>(())
    /// ```
    pub fn evaluate_batch_simd<J, E, S, const N: usize, const R: usize, const C: usize>(
        joint: &J,
        states: &[S],
        out: &mut [Evaluation<E, R, C>],
    ) -> Result<LaneReport, BatchError>
    where
        E: LaneScalar<N>,
        S: Lanes<N>,
        J: Joint<E::Wide, R, C, State = S::Packed> + ?Sized,
    {
        check_lengths(states.len(), out.len())?;
        Ok(evaluate_lanes(joint, states, out))
    }

    /// [`evaluate_batch_simd`] over chunks of
    /// [`PARALLEL_CHUNK`](super::PARALLEL_CHUNK) states on rayon's thread pool
    /// (features `simd` and `parallel`). Results and report are those of
    /// [`evaluate_batch_simd`].
    ///
    /// # Errors
    ///
    /// [`BatchError::LengthMismatch`] if `states.len() != out.len()`; nothing is
    /// written then.
    ///
    /// # Example
    ///
    /// ```
    /// use joint_runtime::batch::{WideF32x8, evaluate_batch, evaluate_batch_simd_par, splat};
    /// use joint_runtime::nalgebra::{Vector3, Vector4};
    /// use joint_runtime::{EulerBody, Evaluation, Joint, TwoBodies};
    ///
    /// #[derive(Joint)]
    /// #[joint(spherical, formulation = euler)]
    /// struct Ball<T> { rho1: Vector3<T>, rho2: Vector3<T> }
    ///
    /// let joint = Ball { rho1: Vector3::new(0.0f32, 0.0, 1.0), rho2: Vector3::zeros() };
    /// let wide: Ball<WideF32x8> = Ball { rho1: splat(&joint.rho1), rho2: splat(&joint.rho2) };
    /// let body = |x: f32| EulerBody { r: Vector3::new(x, 0.0, 0.0), p: Vector4::x(), rdot: Vector3::zeros(), pdot: Vector4::zeros() };
    /// let states: Vec<_> = (0..5000).map(|i| TwoBodies::new(body(i as f32), body(0.5))).collect();
    /// let mut simd = vec![joint.evaluate(&states[0]); 5000];
    /// let mut scalar = simd.clone();
    /// let report = evaluate_batch_simd_par(&wide, &states, &mut simd)?;
    /// evaluate_batch(&joint, &states, &mut scalar)?;
    /// assert_eq!((report.packed, report.padding), (625, 0));
    /// assert_eq!(simd, scalar);
    /// # Ok::<(), joint_runtime::batch::BatchError>(())
    /// ```
    #[cfg(feature = "parallel")]
    pub fn evaluate_batch_simd_par<J, E, S, const N: usize, const R: usize, const C: usize>(
        joint: &J,
        states: &[S],
        out: &mut [Evaluation<E, R, C>],
    ) -> Result<LaneReport, BatchError>
    where
        E: LaneScalar<N> + Send,
        S: Lanes<N> + Sync,
        J: Joint<E::Wide, R, C, State = S::Packed> + Sync + ?Sized,
    {
        use rayon::prelude::*;
        check_lengths(states.len(), out.len())?;
        Ok(states
            .par_chunks(super::PARALLEL_CHUNK)
            .zip(out.par_chunks_mut(super::PARALLEL_CHUNK))
            .map(|(states, out)| evaluate_lanes(joint, states, out))
            .reduce(LaneReport::default, |a, b| a + b))
    }
}
