//! Unit tests of the shared surface cache: stale stamps, LRU eviction, the byte limit.

use super::*;

fn surf(id: &str, n: usize) -> Arc<Surface> {
    Arc::new(Surface {
        machine: "m".into(),
        surface: id.into(),
        nu: n,
        nv: 1,
        points: vec![[0.0; 3]; n],
        normals: vec![[0.0, 0.0, 1.0]; n],
        tool_radius: None,
    })
}

#[test]
fn stale_stamps_miss_and_the_oldest_leave_first() {
    let limit = 48 * 1000;
    let c = SurfaceCache::with_limit(limit);
    c.put((1, 4, 1), surf("a", 4));
    assert!(c.get("m", "a", (1, 4, 1)).is_some());
    // Replaced elsewhere: another stamp misses and drops the entry.
    assert!(c.get("m", "a", (2, 4, 1)).is_none());
    assert!(c.get("m", "a", (1, 4, 1)).is_none());
    // Two surfaces of 60 % of the budget each: the older one leaves.
    let n = 600;
    c.put((1, n, 1), surf("b", n));
    c.put((1, n, 1), surf("c", n));
    assert!(c.get("m", "b", (1, n, 1)).is_none());
    assert!(c.get("m", "c", (1, n, 1)).is_some());
    // Over the whole budget alone: not kept.
    let big = limit / 48 + 1;
    c.put((1, big, 1), surf("d", big));
    assert!(c.get("m", "d", (1, big, 1)).is_none());
    c.forget("m", "c");
    assert!(c.get("m", "c", (1, n, 1)).is_none());
}
