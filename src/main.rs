fn main() -> std::process::ExitCode {
    reflectance::heap::tune();
    reflectance::cli::main()
}
