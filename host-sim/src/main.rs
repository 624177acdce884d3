//! The `parapet` command line; see [`parapet_sim::cli`].
fn main() {
    std::process::exit(parapet_sim::cli::main());
}
