//! The `am-sim` binary; everything lives in the library (`am_sim::cli`).

fn main() -> std::process::ExitCode {
    am_sim::memory::configure_allocator();
    am_sim::cli::main()
}
