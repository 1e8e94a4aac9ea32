//! Link models: what a radio or serial link does to the frames crossing it.

use crate::Moment;
use rand::Rng;
use rand_pcg::Pcg64;
use std::time::Duration;

/// Gilbert–Elliott bursty loss: a two-state Markov chain, evaluated once
/// per frame; each state loses frames with its own probability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GilbertElliott {
    /// Probability of moving from the good to the bad state, per frame.
    pub p_good_to_bad: f64,
    /// Probability of moving from the bad to the good state, per frame.
    pub p_bad_to_good: f64,
    /// Loss probability in the good state.
    pub loss_good: f64,
    /// Loss probability in the bad state.
    pub loss_bad: f64,
}

impl GilbertElliott {
    /// A burst model whose long-run loss rate is `mean_loss`, with bursts of
    /// `mean_burst` frames on average (loss 0 when good, 1 when bad).
    pub fn with_mean(mean_loss: f64, mean_burst: f64) -> Self {
        let p_bg = 1.0 / mean_burst.max(1.0);
        // Stationary bad share = p_gb / (p_gb + p_bg) = mean_loss.
        let loss = mean_loss.clamp(0.0, 0.999);
        GilbertElliott {
            p_good_to_bad: (loss * p_bg / (1.0 - loss)).min(1.0),
            p_bad_to_good: p_bg,
            loss_good: 0.0,
            loss_bad: 1.0,
        }
    }
}

/// One direction of a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkModel {
    /// Fixed delay.
    pub latency: Duration,
    /// Extra delay, uniform in `[0, jitter]`, per frame (frames stay in
    /// order: a frame arrives no earlier than the one sent before it).
    pub jitter: Duration,
    /// Independent loss probability per frame.
    pub loss: f64,
    /// Bursty loss, applied as well.
    pub burst: Option<GilbertElliott>,
    /// Probability a frame is delivered twice.
    pub duplicate: f64,
    /// Probability a frame is held back by an extra `reorder_delay`.
    pub reorder: f64,
    /// The hold-back of a reordered frame.
    pub reorder_delay: Duration,
}

impl LinkModel {
    /// The longest a frame that arrives takes: latency and jitter, and
    /// the hold-back of a reordered frame if any are.
    pub fn longest_delay(&self) -> Duration {
        let held = if self.reorder > 0.0 {
            self.reorder_delay
        } else {
            Duration::ZERO
        };
        self.latency + self.jitter + held
    }

    /// A companion on the FC's serial port (460800 baud): ~1 ms, no loss.
    pub fn serial() -> Self {
        LinkModel {
            latency: Duration::from_millis(1),
            jitter: Duration::from_millis(1),
            loss: 0.0,
            burst: None,
            duplicate: 0.0,
            reorder: 0.0,
            reorder_delay: Duration::from_millis(20),
        }
    }

    /// The same link losing a share `loss` of frames independently.
    pub fn lossy(loss: f64) -> Self {
        LinkModel {
            loss,
            ..Self::serial()
        }
    }
}

/// The state of one link direction during a run.
#[derive(Debug, Clone)]
pub struct Link {
    model: LinkModel,
    bad: bool,
    /// When the last in-order frame arrives: no later frame arrives before.
    tail: Moment,
    /// Frames sent, for drop patterns.
    pub sent: u64,
}

impl Link {
    /// A link in its good state.
    pub fn new(model: LinkModel) -> Self {
        Link {
            model,
            bad: false,
            tail: Moment::ZERO,
            sent: 0,
        }
    }

    /// When one frame sent at `now` arrives: never when lost, twice when
    /// duplicated. The link is a FIFO, as a serial line or a radio modem
    /// is: jitter varies the delay but never lets a frame overtake an
    /// earlier one; only the model's `reorder` share does (and a reordered
    /// frame's lateness does not hold the frames behind it back).
    pub fn transmit(&mut self, now: Moment, rng: &mut Pcg64) -> Vec<Moment> {
        self.sent += 1;
        if self.lost(rng) {
            return Vec::new();
        }
        let m = self.model;
        let copies = if m.duplicate > 0.0 && rng.gen::<f64>() < m.duplicate {
            2
        } else {
            1
        };
        (0..copies)
            .map(|_| {
                let mut d = m.latency;
                if !m.jitter.is_zero() {
                    d += Duration::from_micros(rng.gen_range(0..=m.jitter.as_micros() as u64));
                }
                if m.reorder > 0.0 && rng.gen::<f64>() < m.reorder {
                    return now + d + m.reorder_delay;
                }
                let at = (now + d).max(self.tail);
                self.tail = at;
                at
            })
            .collect()
    }

    fn lost(&mut self, rng: &mut Pcg64) -> bool {
        let m = self.model;
        let mut lost = m.loss > 0.0 && rng.gen::<f64>() < m.loss;
        if let Some(ge) = m.burst {
            let flip = if self.bad {
                ge.p_bad_to_good
            } else {
                ge.p_good_to_bad
            };
            if rng.gen::<f64>() < flip {
                self.bad = !self.bad;
            }
            let p = if self.bad { ge.loss_bad } else { ge.loss_good };
            lost |= rng.gen::<f64>() < p;
        }
        lost
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn loss_rate(model: LinkModel) -> f64 {
        let mut rng = Pcg64::seed_from_u64(1);
        let mut link = Link::new(model);
        let n = 200_000;
        let lost = (0..n)
            .filter(|_| link.transmit(Moment::ZERO, &mut rng).is_empty())
            .count();
        lost as f64 / n as f64
    }

    #[test]
    fn iid_and_bursty_loss_hit_their_mean() {
        assert!((loss_rate(LinkModel::lossy(0.5)) - 0.5).abs() < 0.01);
        let burst = LinkModel {
            burst: Some(GilbertElliott::with_mean(0.3, 8.0)),
            ..LinkModel::serial()
        };
        assert!((loss_rate(burst) - 0.3).abs() < 0.02);
    }

    #[test]
    fn duplication_and_jitter() {
        let mut rng = Pcg64::seed_from_u64(2);
        let mut link = Link::new(LinkModel {
            duplicate: 1.0,
            jitter: Duration::from_millis(5),
            ..LinkModel::serial()
        });
        let d = link.transmit(Moment::ZERO, &mut rng);
        assert_eq!(d.len(), 2);
        assert!(d
            .iter()
            .all(|d| *d >= Moment::from_millis(1) && *d <= Moment::from_millis(6)));
    }

    /// Jitter never reorders: with signing, a frame overtaken by a later one
    /// is refused as a replay, which a serial line never causes.
    #[test]
    fn jitter_keeps_the_order() {
        let mut rng = Pcg64::seed_from_u64(3);
        let mut link = Link::new(LinkModel {
            jitter: Duration::from_millis(50),
            ..LinkModel::serial()
        });
        let mut last = Moment::ZERO;
        for k in 0..10_000u64 {
            let at = link.transmit(Moment(k * 100), &mut rng)[0];
            assert!(at >= last);
            last = at;
        }
    }
}
