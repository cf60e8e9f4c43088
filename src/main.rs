fn main() -> std::process::ExitCode {
    hilcam::cli::main()
}
