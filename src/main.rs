//! The `hilcam` binary: the command line over hilcam-core (and hilcam-lab with the
//! default `lab` feature).

mod cli;

fn main() -> std::process::ExitCode {
    hilcam_core::heap::keep_frame_pages();
    cli::main()
}
