//! Small shared tools: durable file writes, allocator tuning, progress reporting, the
//! seeded random number generator and sharding (`--shard I/N`, `merge`).

pub mod durable;
pub mod parallel;
pub mod progress;
pub mod rng;
pub mod shard;

/// The JSON keys of an options type's default value, sorted: the keys a caller that refuses
/// unknown ones accepts (the type must serialize every field, `None` included).
pub fn json_keys<T: serde::Serialize + Default>() -> Vec<String> {
    match serde_json::to_value(T::default()) {
        Ok(serde_json::Value::Object(map)) => map.keys().cloned().collect(),
        _ => Vec::new(),
    }
}

/// For the tests that compare a SIMD kernel with its portable twin: whether this CPU runs
/// the kernel's instruction sets (`"avx"`, `"avx2"` or `"avx2,fma"`), said in the test's
/// output. With `REFLECTANCE_REQUIRE_SIMD` set (CI sets it where the CPU has AVX2), a CPU
/// without them fails the test rather than compare portable code with itself.
#[cfg(test)]
pub(crate) fn simd_under_test(features: &str) -> bool {
    #[cfg(target_arch = "x86_64")]
    let supported = match features {
        "avx" => std::arch::is_x86_feature_detected!("avx"),
        "avx2" => std::arch::is_x86_feature_detected!("avx2"),
        "avx2,fma" => {
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
        }
        other => panic!("no SIMD kernel uses {other}"),
    };
    #[cfg(not(target_arch = "x86_64"))]
    let supported = false;
    if supported {
        eprintln!("the {features} kernel is compared with the portable one");
    } else {
        assert!(
            std::env::var_os("REFLECTANCE_REQUIRE_SIMD").is_none(),
            "REFLECTANCE_REQUIRE_SIMD is set but this CPU lacks {features}"
        );
        eprintln!("this CPU lacks {features}: only the portable path is tested");
    }
    supported
}
