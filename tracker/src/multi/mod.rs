//! Several arrays, one clock (issue 14, ALGORITHMS.md §9, paper §VI): the host's multi-array
//! maths as plain library pieces, each fed with plain structs (no wire types), one concept a
//! module. Nothing here is wired into [`crate::tracker::Tracker`] yet; this is how each piece is
//! meant to be fed:
//!
//! - [`clock`]: every BEACON frame becomes a [`clock::BeaconArrival`] (array id, `sample_index +
//!   fraction` in the board's own samples, quality) pushed with a *coarse* common time of the
//!   arrival (the host's link time of the board's samples, [`clock::LinkAlignment`]); the model
//!   groups arrivals of one emission across arrays, solves every array's map t = a_p + b_p·n
//!   against the reference array and reports residuals and a status per array. The intake then
//!   turns any sample index of a synced array (DoA blocks, snippets) into common time with
//!   [`clock::ClockModel::common_time`]. Site: [`crate::site::SiteSync::beacons`], array positions,
//!   `speed_of_sound_mps`.
//! - [`multilat`]: inter-array delays T_pq on the common clock (GCC-PHAT of snippets, branch
//!   `snippet`) become [`multilat::RangeDifference`]s (c·T_pq with its σ, the two arrays'
//!   positions); Gauss–Newton from the single-array estimate (optionally with it as a prior, which
//!   three arrays need: their three differences hold only two independent equations), out comes
//!   the fix with its covariance. [`multilat::Hyperboloid`] is eq. 8 for one pair.
//! - [`select`]: each array's position and smoothed azimuth variance (e.g. the square of
//!   [`crate::doa::DoaState::erratic_rad`], which is the variance around the DoA trend, so that a
//!   moving drone is not mistaken for an unstable array) → Algorithm 1's arrays for `multilat`.
//! - [`fusion`]: per output step, the AIM filter's position and, when there is one, the
//!   multi-array fix → the complementary filter's position (causal for `aim track`, the FFT form
//!   for replay).
//! - [`triangulate`]: each array's smoothed DoA ([`triangulate::ray_from_doa`]) → the least-squares
//!   closest point of the rays, the paper's baseline (Fig. 23).

pub mod clock;
pub mod fusion;
pub mod multilat;
pub mod select;
pub mod triangulate;
