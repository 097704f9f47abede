//! Thread counts for the cores' scoped-thread splits.

/// Threads to use when a caller asks for `asked` (0 = the machine's available
/// parallelism, 1 when that cannot be read).
pub fn resolve_threads(asked: usize) -> usize {
    if asked == 0 {
        std::thread::available_parallelism().map_or(1, |t| t.get())
    } else {
        asked
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_means_all_cores_and_others_pass_through() {
        assert!(resolve_threads(0) >= 1);
        assert_eq!(resolve_threads(3), 3);
    }
}
