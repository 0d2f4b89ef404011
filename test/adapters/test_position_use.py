"""ins_fusion/adapters/position_use.py: the degraded state says for how long and why, and the
recovery names its cause."""

from __future__ import annotations

from ins_fusion.adapters.position_use import AFTER_GNSS_OUTAGE, AFTER_IMU_GAP, PositionUse


def counters(used: int, rejected: int = 0, gated: int = 0, too_old: int = 0) -> dict[str, int]:
    return {"used": used, "rejected": rejected, "gated": gated, "too_old": too_old}


def test_no_fix_received_since_the_last_position_used():
    use = PositionUse(0.0)
    use.update(counters(5), fixes_received=5, now_s=10.0)
    use.update(counters(5), fixes_received=5, now_s=25.0)
    assert use.degraded(counters(5), 5, 25.0) == (
        "degraded: no GNSS position used for 15 s (no GNSS fix received)"
    )
    assert use.cause() == AFTER_GNSS_OUTAGE


def test_fixes_that_came_and_why_each_was_not_used():
    use = PositionUse(0.0)
    use.update(counters(5, rejected=1, gated=1), fixes_received=6, now_s=10.0)
    later = counters(5, rejected=1 + 9, gated=1 + 6, too_old=2)
    assert use.degraded(later, 16, 22.4) == (
        "degraded: no GNSS position used for 12 s (10 fixes received: 6 gated by the innovation"
        " test, 2 too old, 1 refused (fix type, covariance))"
    )
    assert use.degraded(counters(5, 1, 1), 8, 22.4).endswith("2 fixes received: none taken yet)")


def test_an_imu_gap_is_named_as_the_cause():
    use = PositionUse(0.0)
    use.update(counters(3), fixes_received=3, now_s=10.0)
    use.imu_gap(12.0)
    assert use.cause() == AFTER_IMU_GAP
    assert use.degraded(counters(3), 5, 20.0).endswith("(the IMU was silent)")
    use.update(counters(4), fixes_received=6, now_s=21.0)  # a position used after the gap
    assert use.cause() == AFTER_GNSS_OUTAGE
