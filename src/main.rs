fn main() -> std::process::ExitCode {
    reflectance::cli::main()
}
