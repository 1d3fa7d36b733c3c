//! The substep count's answer to cells near collapse. A soft body crushed against a surface
//! (jelly tipping over an edge it is stuck to by friction, a capsule pressing into it) can
//! need more substeps than its stiffness and speed ask for: one sweep of the cells a substep
//! leaves the corners at the pressure point squeezed past the collapse barrier and, at too
//! few substeps, folded. Measured: a 0.5 m jelly cube on 32³ nodes pushed broadside by a
//! capsule at 1 m/s, in 1/60 s frames, inverted up to 107 cells a frame at the 24 substeps
//! the speed cap allowed (speeds of 15 m/s where corners flipped), 9 cell-frames in all at a
//! fixed 60 and none at a fixed 120.
//!
//! So each frame starts by measuring the most collapsed corner of any cell
//! ([`super::cells::CellSet::most_collapsed`]); below [`CROWDED_J`] the frame doubles the
//! substeps the other bounds chose, once more for each frame that stays crowded (up to the
//! impact cap). Once [`HOLD_SECONDS`] have passed since the last doubling, a frame above
//! [`RELIEVED_J`] halves them again, one doubling a frame (let go at once, the relief the
//! doubling bought ends with it: measured on 16³, the count then swung each frame between 16
//! and 32 and the low frames still folded).
//!
//! Tried and left out: doubling also when the ratio falls so fast that, at the last frame's
//! rate, a corner would fold within the frame. It caught the one cell a capsule entering a
//! 16³ jelly still folds (in the frame after one that started above the threshold), but it
//! also doubled every impact frame of a rubber ball (its corners dip to 0.24 for a frame),
//! and a ball's rebound grows with the substeps of its impact (on a slab collider: 0.39 m
//! at 30 a frame, 0.51 at 60, 0.58 at 120): the ball kept bouncing 0.3 m high for seconds.

/// A corner's volume ratio below which the next frame takes twice the substeps (half the
/// collapse barrier's [`super::cells::COLLAPSE_J`]: a capsule pressing a 16³ jelly holds
/// its cells at 0.16–0.19, a tipping block's pivot edge reaches 0.03 a frame before it folds).
pub(crate) const CROWDED_J: f64 = 0.1;
/// A corner's volume ratio above which the doublings are let go, one a frame: the collapse
/// barrier's, no corner pressed against it (at 0.15 a doubled 16³ jelly sat at 0.13–0.18,
/// let go and folded the next frame).
pub(crate) const RELIEVED_J: f64 = super::cells::COLLAPSE_J;
/// Simulated seconds a doubling is kept at least.
pub(crate) const HOLD_SECONDS: f64 = 0.1;

/// How many times over the substeps are doubled, and for which frame start that was decided.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Crowding {
    level: u32,
    /// When the level last rose, s.
    raised_at: f64,
    /// The time (bits) of the last decision and the level before it: asked again for the same
    /// frame start (the pipeline's budget check, then the frame), the answer is the same.
    last: Option<(u64, u32)>,
}

impl Crowding {
    /// The doublings for the frame starting at `time` whose most collapsed corner has volume
    /// ratio `ratio`, at most `max_level`.
    pub(crate) fn update(&mut self, time: f64, ratio: f64, max_level: u32) -> u32 {
        let before = match self.last {
            Some((t, level)) if t == time.to_bits() => level,
            _ => self.level,
        };
        let level = if ratio < CROWDED_J {
            self.raised_at = time;
            before + 1
        } else if ratio >= RELIEVED_J && time - self.raised_at >= HOLD_SECONDS {
            before.saturating_sub(1)
        } else {
            before
        };
        self.last = Some((time.to_bits(), before));
        self.level = level.min(max_level);
        self.level
    }

    /// One doubling more, from the frame starting at `time` on, held as a crowded frame's
    /// is: that frame folded a cell and is taken again at twice its substeps.
    pub(crate) fn raise(&mut self, time: f64) {
        self.level += 1;
        self.raised_at = time;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crowded_frames_double_and_relieved_ones_halve_one_step_at_a_time() {
        let mut c = Crowding::default();
        assert_eq!(c.update(0.0, 1.0, 4), 0);
        assert_eq!(c.update(0.1, 0.05, 4), 1);
        assert_eq!(c.update(0.2, -0.3, 4), 2);
        // Relieved, but within the hold of the last doubling: kept.
        assert_eq!(c.update(0.25, 0.5, 4), 2);
        // Between the two thresholds: held.
        assert_eq!(c.update(0.3, 0.12, 4), 2);
        assert_eq!(c.update(0.4, 0.5, 4), 1);
        assert_eq!(c.update(0.5, 0.5, 4), 0);
        assert_eq!(c.update(0.6, 0.5, 4), 0);
    }

    #[test]
    fn asking_again_for_the_same_frame_gives_the_same_answer_and_the_cap_holds() {
        let mut c = Crowding::default();
        assert_eq!(c.update(0.0, 0.0, 2), 1);
        assert_eq!(c.update(0.0, 0.0, 2), 1);
        assert_eq!(c.update(0.1, 0.0, 2), 2);
        assert_eq!(c.update(0.2, 0.0, 2), 2);
    }
}
