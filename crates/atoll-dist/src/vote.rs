//! A repeated "does any of us still have work?" vote among the devices of
//! one ring: every member must take the same number of ring steps, so they
//! decide together when a wave is finished.

use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

#[derive(Default)]
struct State {
    arrived: usize,
    any: bool,
    generation: u64,
    result: bool,
}

/// A reusable barrier that also ORs one flag per member.
pub struct Vote {
    members: usize,
    state: Mutex<State>,
    done: Condvar,
}

impl Vote {
    pub fn new(members: usize) -> Self {
        Vote { members: members.max(1), state: Mutex::new(State::default()), done: Condvar::new() }
    }

    /// Blocks until every member has voted this round; true when any voted
    /// true. Also returns how long this member waited for the others.
    pub fn any(&self, mine: bool) -> (bool, Duration) {
        let start = Instant::now();
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let generation = s.generation;
        s.any |= mine;
        s.arrived += 1;
        if s.arrived == self.members {
            // The last to arrive closes the round. `result` stays valid until
            // the next round closes, which needs every member, including
            // those still to wake up and read it.
            s.result = s.any;
            s.any = false;
            s.arrived = 0;
            s.generation += 1;
            self.done.notify_all();
            return (s.result, start.elapsed());
        }
        while s.generation == generation {
            s = self.done.wait(s).unwrap_or_else(|p| p.into_inner());
        }
        (s.result, start.elapsed())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn any_is_the_or_of_every_member_every_round() {
        let vote = Vote::new(3);
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..3)
                .map(|member| {
                    let vote = &vote;
                    scope.spawn(move || {
                        // Round r: only member r % 3 votes true; round 9: nobody.
                        (0..10).map(|r| vote.any(r < 9 && r % 3 == member).0).collect::<Vec<_>>()
                    })
                })
                .collect();
            for h in handles {
                let rounds = h.join().unwrap();
                assert_eq!(rounds[..9], [true; 9]);
                assert!(!rounds[9]);
            }
        });
    }

    #[test]
    fn a_single_member_never_waits_for_anyone() {
        let vote = Vote::new(1);
        assert!(vote.any(true).0);
        assert!(!vote.any(false).0);
    }
}
