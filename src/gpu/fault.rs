//! Fault injection for tests: makes chosen allocations fail with out-of-device-memory and a
//! chosen submission report a lost device, so the error paths above can be exercised on any
//! driver. Off unless asked for (`ContextDesc::faults`, or `CAUSTICA_FAULT` in the
//! environment); costs one uncontended lock per allocation and submission.
//!
//! Syntax of `CAUSTICA_FAULT`: comma-separated items
//! * `oom:LABEL`: the first allocation whose label contains `LABEL` fails (e.g. `oom:light A`);
//! * `oom-always:LABEL`: every allocation whose label contains `LABEL` fails;
//! * `lost:N`: the N-th submission (1-based) reports `VK_ERROR_DEVICE_LOST` without running;
//! * `hang:N`: the wait for the N-th submission gives up at once, as if the device had not
//!   finished within the fence timeout (the work itself runs on);
//! * `validation`: one deliberately invalid Vulkan call when the context is created (checks
//!   how validation errors are reported; needs the validation layer).

use std::sync::Mutex;

/// What to break, parsed from the `CAUSTICA_FAULT` syntax.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Faults {
    /// (label substring, fail every time).
    pub oom: Vec<(String, bool)>,
    pub lost_at_submit: Option<u64>,
    pub hang_at_submit: Option<u64>,
    pub validation_error: bool,
}

impl Faults {
    pub fn parse(spec: &str) -> Result<Faults, String> {
        let mut f = Faults::default();
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if item == "validation" {
                f.validation_error = true;
                continue;
            }
            match item.split_once(':') {
                Some(("oom", label)) => f.oom.push((label.to_string(), false)),
                Some(("oom-always", label)) => f.oom.push((label.to_string(), true)),
                Some((kind @ ("lost" | "hang"), n)) => {
                    let n = n
                        .parse::<u64>()
                        .ok()
                        .filter(|n| *n > 0)
                        .ok_or_else(|| format!("'{item}': expected {kind}:N with N ≥ 1"))?;
                    if kind == "lost" {
                        f.lost_at_submit = Some(n);
                    } else {
                        f.hang_at_submit = Some(n);
                    }
                }
                _ => {
                    return Err(format!(
                        "'{item}': expected oom:LABEL, oom-always:LABEL, lost:N, hang:N or validation"
                    ))
                }
            }
        }
        Ok(f)
    }

    pub fn is_empty(&self) -> bool {
        self.oom.is_empty() && self.lost_at_submit.is_none() && self.hang_at_submit.is_none() && !self.validation_error
    }
}

/// The injector's state inside a context.
#[derive(Default)]
pub(crate) struct Injector {
    state: Mutex<(Faults, u64)>,
}

impl Injector {
    pub(crate) fn new(faults: Faults) -> Self {
        Injector {
            state: Mutex::new((faults, 0)),
        }
    }

    /// True when the allocation labelled `label` must fail.
    pub(crate) fn allocation_fails(&self, label: &str) -> bool {
        let Ok(mut s) = self.state.lock() else { return false };
        let oom = &mut s.0.oom;
        match oom.iter().position(|(l, _)| label.contains(l.as_str())) {
            Some(i) => {
                if !oom[i].1 {
                    oom.remove(i);
                }
                true
            }
            None => false,
        }
    }

    /// Counts a submission; returns (report a lost device, give up waiting at once).
    pub(crate) fn next_submission(&self) -> (bool, bool) {
        let Ok(mut s) = self.state.lock() else {
            return (false, false);
        };
        s.1 += 1;
        (s.0.lost_at_submit == Some(s.1), s.0.hang_at_submit == Some(s.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_fires_as_specified() {
        let f = Faults::parse("oom:light A, lost:3,validation,hang:2").unwrap();
        assert!(f.validation_error);
        assert_eq!(f.hang_at_submit, Some(2));
        let f = Faults {
            hang_at_submit: None,
            ..f
        };
        assert_eq!(f.oom, vec![("light A".to_string(), false)]);
        let inj = Injector::new(f);
        assert!(!inj.allocation_fails("volume"));
        assert!(inj.allocation_fails("light A"));
        assert!(!inj.allocation_fails("light A"), "oom: fires once");
        let seen: Vec<_> = (0..4).map(|_| inj.next_submission()).collect();
        assert_eq!(seen, [(false, false), (false, false), (true, false), (false, false)]);
        let always = Injector::new(Faults::parse("oom-always:x").unwrap());
        assert!(always.allocation_fails("x") && always.allocation_fails("x"));
        for bad in ["oom", "lost:0", "lost:x", "boom:1", "hang:"] {
            assert!(Faults::parse(bad).is_err(), "{bad}");
        }
    }
}
