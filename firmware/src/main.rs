//! Placeholder: the embassy firmware lands with its own issue.
fn main() {}
