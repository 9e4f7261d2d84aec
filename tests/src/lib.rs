//! Whole-system tests across the workspace crates live in `tests/tests/`; this library is
//! empty and exists so cargo treats the folder as a workspace member.
