//! The machine a run's times were measured on: the CPU as the kernel names it and the vector
//! code this build of furnace was compiled for (they set its speed, never its numbers).

/// The vector extensions this build was compiled to use, e.g. `"sse4.2 avx avx2 fma"` (the
/// default build leaves AVX-512 out even where the CPU has it: docs/performance.md, "Without
/// AVX-512").
pub fn vector_code() -> String {
    let on: Vec<&str> = [
        ("sse4.2", cfg!(target_feature = "sse4.2")),
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("avx512f", cfg!(target_feature = "avx512f")),
        ("neon", cfg!(target_feature = "neon")),
    ]
    .into_iter()
    .filter_map(|(name, enabled)| enabled.then_some(name))
    .collect();
    if on.is_empty() {
        "none beyond the baseline".into()
    } else {
        on.join(" ")
    }
}

/// The CPU as `/proc/cpuinfo` names it (model name, and family/model/stepping where given),
/// with the logical CPUs this process may use; the architecture alone where the file is not
/// there (not Linux) or names no model.
pub fn cpu() -> String {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| cpu_from_cpuinfo(&text))
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    format!("{model}, {threads} logical CPUs")
}

/// The first processor's model line of a `/proc/cpuinfo` text, with its family, model and
/// stepping when listed (x86); None when it names no model.
fn cpu_from_cpuinfo(text: &str) -> Option<String> {
    let field = |key: &str| {
        text.lines()
            .find_map(|l| {
                let (k, v) = l.split_once(':')?;
                (k.trim() == key).then(|| v.trim().to_string())
            })
            .filter(|v| !v.is_empty())
    };
    let name = field("model name")
        .or_else(|| field("Model"))
        .or_else(|| field("cpu model"))?;
    match (field("cpu family"), field("model"), field("stepping")) {
        (Some(f), Some(m), Some(s)) => Some(format!("{name} (family {f} model {m} stepping {s})")),
        _ => Some(name),
    }
}

/// One line for a report: the CPU and the build's vector code.
pub fn description() -> String {
    format!(
        "{}; furnace built for {} with {}",
        cpu(),
        std::env::consts::ARCH,
        vector_code()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_line_reads_the_first_processor_and_its_family() {
        let x86 = "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 17\n\
                   model name\t: AMD EPYC\nstepping\t: 1\n\nprocessor\t: 1\nmodel name\t: other\n";
        assert_eq!(
            cpu_from_cpuinfo(x86).as_deref(),
            Some("AMD EPYC (family 25 model 17 stepping 1)")
        );
        // an Arm kernel lists no model name per processor; some list "Model" at the end
        assert_eq!(cpu_from_cpuinfo("processor\t: 0\nBogoMIPS\t: 50\n"), None);
        assert_eq!(
            cpu_from_cpuinfo("Model\t\t: Raspberry Pi 4\n").as_deref(),
            Some("Raspberry Pi 4")
        );
        assert_eq!(cpu_from_cpuinfo(""), None);
        assert_eq!(cpu_from_cpuinfo("model name\t:\n"), None);
    }

    #[test]
    fn the_description_names_the_build_and_agrees_with_its_flags() {
        let d = description();
        assert!(d.contains(std::env::consts::ARCH), "{d}");
        assert!(d.contains("logical CPUs"), "{d}");
        assert_eq!(
            vector_code().split(' ').any(|f| f == "avx2"),
            cfg!(target_feature = "avx2")
        );
    }
}
