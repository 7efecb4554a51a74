//! Shards: a deterministic split of a suite's expanded checks over N CI jobs, and the exact merge
//! of their results. The family-wise correction always spans the whole suite (each shard knows
//! every check), so a merged run has the verdicts, estimates and p-values of a single run.

use super::outcome::{Outcome, RunReport};
use std::collections::BTreeMap;
use thiserror::Error;

/// Largest number of shards (a CI matrix rarely exceeds a few hundred jobs).
pub const MAX_SHARDS: usize = 4096;

/// This job's part of the suite: shard `index` (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 1 ..= count.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

/// A shard specification or a merge that cannot be made.
#[derive(Debug, Error, PartialEq)]
pub enum ShardError {
    /// `--shard` is not K/N with 1 ≤ K ≤ N ≤ MAX_SHARDS.
    #[error("--shard {0:?} must be K/N with 1 <= K <= N <= {MAX_SHARDS}, e.g. 2/4")]
    Spec(String),
    /// The shard results do not belong to one run.
    #[error("{0}")]
    Mismatch(String),
}

impl Shard {
    /// Parses `K/N`.
    pub fn parse(s: &str) -> Result<Shard, ShardError> {
        let bad = || ShardError::Spec(crate::limits::quote(s));
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            k.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if index == 0 || index > count || count > MAX_SHARDS {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// This shard's contiguous part of `total` ordered units (sample blocks, chunks, runs):
    /// [(K−1)·total/N, K·total/N); None when there are fewer units than shards.
    pub fn part_of(&self, total: u64) -> Option<std::ops::Range<u64>> {
        let n = self.count as u64;
        let i = self.index as u64 - 1;
        (n <= total).then(|| i * total / n..(i + 1) * total / n)
    }
}

/// The shard (1-based) of each check: longest-processing-time-first over `costs` (seconds, or
/// any positive weight; non-finite or non-positive counts as 1), ties broken by position, each
/// check to the shard with the least total so far (the lowest index among equals). The same
/// inputs always give the same split.
pub fn partition(costs: &[f64], count: usize) -> Vec<usize> {
    let count = count.max(1);
    let cost = |i: usize| {
        let c = costs[i];
        if c.is_finite() && c > 0.0 {
            c
        } else {
            1.0
        }
    };
    let mut order: Vec<usize> = (0..costs.len()).collect();
    order.sort_by(|&a, &b| cost(b).total_cmp(&cost(a)).then(a.cmp(&b)));
    let mut load = vec![0.0f64; count];
    let mut out = vec![0usize; costs.len()];
    for i in order {
        let mut best = 0;
        for s in 1..count {
            if load[s] < load[best] {
                best = s;
            }
        }
        load[best] += cost(i);
        out[i] = best + 1;
    }
    out
}

/// Merges the shard reports of one renderer (`(file, report)`) into the report of the whole
/// run: checks that every part comes from the same suite, seed, settings, furnace version and
/// renderer, that each shard 1..=N appears once, and that every check of the suite has exactly
/// one outcome; outcomes come back in the suite's run order.
pub fn merge(parts: &[(String, RunReport)]) -> Result<RunReport, ShardError> {
    let mismatch = |m: String| Err(ShardError::Mismatch(m));
    let Some((first_file, first)) = parts.first() else {
        return mismatch("no shard results given".into());
    };
    let Some(info) = &first.shard else {
        return mismatch(format!(
            "{first_file} is not a shard's result (it has no \"shard\" field: run furnace check --shard K/N)"
        ));
    };
    if first.correction != "sidak" {
        return mismatch(format!(
            "{first_file}: correction {:?}; shards need sidak (Holm's step-down needs every p-value at once)",
            first.correction
        ));
    }
    let mut seen: BTreeMap<usize, &str> = BTreeMap::new();
    for (file, r) in parts {
        let Some(s) = &r.shard else {
            return mismatch(format!(
                "{file} is not a shard's result (no \"shard\" field)"
            ));
        };
        let differs = |what: &str, a: String, b: String| {
            mismatch(format!(
                "{file} and {first_file} are not shards of one run: {what} {a} vs {b}"
            ))
        };
        if r.furnace_version != first.furnace_version {
            return differs(
                "furnace version",
                r.furnace_version.clone(),
                first.furnace_version.clone(),
            );
        }
        if r.renderer != first.renderer {
            return differs("renderer", r.renderer.clone(), first.renderer.clone());
        }
        if r.manifests != first.manifests {
            return differs(
                "manifests",
                format!("{:?}", r.manifests),
                format!("{:?}", first.manifests),
            );
        }
        if r.seed != first.seed {
            return differs("seed", r.seed.to_string(), first.seed.to_string());
        }
        if s.suite != info.suite {
            // (before the correction, whose test count differs too when the suites do)
            let only = |a: &[String], b: &[String]| a.iter().find(|n| !b.contains(n)).cloned();
            let which = match (only(&s.suite, &info.suite), only(&info.suite, &s.suite)) {
                (Some(n), _) => format!("{n:?} is in {file}'s suite and not in {first_file}'s"),
                (None, Some(n)) => format!("{n:?} is in {first_file}'s suite and not in {file}'s"),
                (None, None) => "the same checks in another order".into(),
            };
            return mismatch(format!(
                "{file} and {first_file} are not shards of one run: they split different suites ({} and {} checks; {which}): run every shard with the same manifests and --filter",
                s.suite.len(),
                info.suite.len()
            ));
        }
        if r.family_alpha.to_bits() != first.family_alpha.to_bits()
            || r.correction != first.correction
            || r.stochastic_tests != first.stochastic_tests
        {
            return differs(
                "correction",
                format!(
                    "{} at {} over {}",
                    r.correction, r.family_alpha, r.stochastic_tests
                ),
                format!(
                    "{} at {} over {}",
                    first.correction, first.family_alpha, first.stochastic_tests
                ),
            );
        }
        if r.looks != first.looks || r.power.map(f64::to_bits) != first.power.map(f64::to_bits) {
            let plan = |r: &RunReport| match r.power {
                Some(d) => format!("{} looks, power {d}", r.looks),
                None => format!("{} looks", r.looks),
            };
            return differs("sample plan", plan(r), plan(first));
        }
        if s.count != info.count {
            return differs("shard count", s.count.to_string(), info.count.to_string());
        }
        if let Some(other) = seen.insert(s.index, file) {
            return mismatch(format!(
                "shard {}/{} given twice: {other} and {file}",
                s.index, s.count
            ));
        }
    }
    let missing: Vec<String> = (1..=info.count)
        .filter(|k| !seen.contains_key(k))
        .map(|k| format!("{k}/{}", info.count))
        .collect();
    if !missing.is_empty() {
        return mismatch(format!(
            "shard{} {} missing ({} of {} given)",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            seen.len(),
            info.count
        ));
    }
    let mut by_name: BTreeMap<&str, &Outcome> = BTreeMap::new();
    for (file, r) in parts {
        for o in &r.outcomes {
            if by_name.insert(&o.name, o).is_some() {
                return mismatch(format!(
                    "check {:?} appears twice (again in {file})",
                    o.name
                ));
            }
        }
    }
    let mut outcomes = Vec::with_capacity(info.suite.len());
    for name in &info.suite {
        match by_name.remove(name.as_str()) {
            Some(o) => outcomes.push(o.clone()),
            None => return mismatch(format!("no shard has a result for check {name:?}")),
        }
    }
    if let Some(extra) = by_name.keys().next() {
        return mismatch(format!(
            "check {extra:?} is not in the suite the shards name"
        ));
    }
    Ok(RunReport {
        outcomes,
        // the jobs ran side by side: the run took as long as its longest shard
        seconds: parts.iter().map(|(_, r)| r.seconds).fold(0.0, f64::max),
        machine: machines(parts),
        shard: None,
        ..first.clone()
    })
}

/// The distinct machines the shards ran on, in shard order, joined by " | " (the jobs of a CI
/// matrix may land on different CPUs; a shard without a record adds nothing).
fn machines(parts: &[(String, RunReport)]) -> String {
    let mut seen: Vec<&str> = Vec::new();
    for (_, r) in parts {
        if !r.machine.is_empty() && !seen.contains(&r.machine.as_str()) {
            seen.push(&r.machine);
        }
    }
    seen.join(" | ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_merge_names_each_distinct_machine_once_in_shard_order() {
        let run = |machine: &str| RunReport {
            furnace_version: "0.1.0".into(),
            renderer: "furnace 0.1.0".into(),
            manifests: vec![],
            seed: 1,
            family_alpha: 0.01,
            correction: "sidak".into(),
            stochastic_tests: 0,
            looks: String::new(),
            power: None,
            outcomes: vec![],
            seconds: 1.0,
            machine: machine.into(),
            shard: None,
        };
        let parts: Vec<(String, RunReport)> = ["B", "", "A", "B"]
            .iter()
            .map(|m| (format!("{m}.json"), run(m)))
            .collect();
        assert_eq!(machines(&parts), "B | A");
        assert_eq!(machines(&parts[1..2]), "");
        assert_eq!(machines(&parts[..1]), "B");
    }

    #[test]
    fn specs_parse_and_bad_ones_are_named() {
        assert_eq!(Shard::parse("2/4"), Ok(Shard { index: 2, count: 4 }));
        for bad in ["0/4", "5/4", "4", "a/b", "1/0", "1/5000", ""] {
            assert!(
                matches!(Shard::parse(bad), Err(ShardError::Spec(_))),
                "{bad}"
            );
        }
    }

    #[test]
    fn partition_balances_and_is_deterministic() {
        let costs = [5.0, 1.0, 1.0, 1.0, 1.0, 1.0, f64::NAN, 0.0];
        let p = partition(&costs, 2);
        assert_eq!(p, partition(&costs, 2));
        let load = |k| -> f64 {
            (0..costs.len())
                .filter(|&i| p[i] == k)
                .map(|i| if costs[i] > 0.0 { costs[i] } else { 1.0 })
                .sum()
        };
        assert_eq!((load(1), load(2)), (6.0, 6.0));
        // more shards than checks: some shards are empty, every check is placed once
        let p = partition(&[1.0; 3], 7);
        assert_eq!(p, vec![1, 2, 3]);
    }
}
