fn main() -> std::process::ExitCode {
    if !reflectance::tune_heap() {
        eprintln!("warning: the allocator refused the heap thresholds (see src/heap.rs)");
    }
    reflectance::command_line()
}
