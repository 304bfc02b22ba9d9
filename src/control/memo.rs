//! The last value of a function of rarely changing inputs (limits, a held
//! heading, the step size), so that the laws pay for `tan`, `sin_cos`, `exp`
//! or a division once per change instead of once per step.

/// The last value of a function of rarely changing inputs (limits, a held
/// heading, the step size), keyed on their exact bits: the same value as
/// calling the function, computed once per change.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Memo<K, T> {
    last: Option<(K, T)>,
}

impl<K: Copy + PartialEq, T: Copy> Memo<K, T> {
    /// `f()` for `key`, from the memo when `key` is the last one.
    pub(super) fn get(&mut self, key: K, f: impl FnOnce() -> T) -> T {
        match self.last {
            Some((k, v)) if k == key => v,
            _ => {
                let v = f();
                self.last = Some((key, v));
                v
            }
        }
    }
}
