//! What the worker tells the coordinator about its machine beyond the core count: the CPU
//! model. The same cell and seed trained on two CPUs can end in different gaits (BENCHMARKS,
//! session 34), so a recording that spans machines stores which CPU trained each attempt.

/// The CPU model of this machine, e.g. `AMD EPYC (family 25 model 17)`; empty where
/// `/proc/cpuinfo` cannot be read (not Linux).
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .map(|s| cpu_model_from(&s))
        .unwrap_or_default()
}

/// The CPU model named by the first processor of a `/proc/cpuinfo` text: its `model name`,
/// with the x86 `cpu family` and `model` numbers, which tell apart CPUs that share a
/// marketing name (the same "AMD EPYC" is Zen 2 to Zen 5).
pub fn cpu_model_from(cpuinfo: &str) -> String {
    let first = cpuinfo.split("\n\n").next().unwrap_or_default();
    let field = |key: &str| {
        first.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            (k.trim() == key).then(|| v.trim().to_string())
        })
    };
    let name = field("model name")
        .or_else(|| field("Model"))
        .or_else(|| field("CPU part"))
        .unwrap_or_default();
    match (field("cpu family"), field("model")) {
        (Some(f), Some(m)) => format!("{name} (family {f} model {m})").trim().to_string(),
        _ => name,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_first_processor() {
        let x86 = "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 17\n\
                   model name\t: AMD EPYC\nstepping\t: 1\n\nprocessor\t: 1\nmodel name\t: other\n";
        assert_eq!(cpu_model_from(x86), "AMD EPYC (family 25 model 17)");
        let arm =
            "processor\t: 0\nBogoMIPS\t: 50.00\nCPU part\t: 0xd0c\n\nModel\t\t: Raspberry Pi\n";
        assert_eq!(cpu_model_from(arm), "0xd0c");
        assert_eq!(cpu_model_from(""), "");
    }

    #[test]
    fn this_machine_has_a_cpu_model() {
        if cfg!(target_os = "linux") {
            assert!(!cpu_model().is_empty());
        }
    }
}
