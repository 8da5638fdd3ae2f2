fn main() -> std::process::ExitCode {
    if !reflectance::heap::tune() {
        eprintln!("warning: the allocator refused the heap thresholds (see src/heap.rs)");
    }
    reflectance::cli::main()
}
