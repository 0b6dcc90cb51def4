"""Simulated RTK receiver: lines parse, carry the truth within the noise, follow the schedule."""

from __future__ import annotations

import math

import numpy as np
import pynmea2
import pytest

from drivers.samples import FixQuality
from gateway.estimation.geodesy import lla_to_ned, ned_to_lla
from sim_bus.gnss_receiver import (
    KNOT_MPS,
    FixInterval,
    GnssReceiverConfig,
    ReceiverOutput,
    simulate_receiver,
)
from sim_bus.truth import Truth

ORIGIN = np.array([52.2, 10.5, 80.0])
T0 = 1_700_000_000.0123  # not on an epoch: the first epoch is the next multiple of 1/rate
DT = 4.0 / 819.2


def kinematic_truth(
    t: np.ndarray, pos_ned: np.ndarray, vel_ned: np.ndarray, yaw: np.ndarray
) -> Truth:
    """A Truth whose antenna is the reference point (zero lever arms), level attitude."""
    n = len(t)
    zeros = np.zeros((n, 3))
    lla = ned_to_lla(pos_ned, ORIGIN)
    rpy = np.column_stack((np.zeros(n), np.zeros(n), yaw))
    speed = np.linalg.norm(vel_ned, axis=1)
    return Truth(
        t=t, pos_ned_m=pos_ned, lla=lla, vel_ned_mps=vel_ned, rpy_rad=rpy, w_ib_b=zeros,
        f_ib_b_imu=zeros, pos_ant_ned_m=pos_ned, lla_ant=lla, vel_ant_ned_mps=vel_ned,
        reversing=np.zeros(n, bool), stationary=speed < 1e-6, bias_g_rps=zeros,
        bias_a_mps2=zeros, origin_lla=ORIGIN, dt_s=DT,
    )  # fmt: skip


def straight_truth(
    duration_s: float, vel_ne: tuple[float, float], reversing: bool = False
) -> Truth:
    """Constant velocity along a line; yaw opposite to the motion when reversing."""
    t = T0 + np.arange(0.0, duration_s, DT)
    vel = np.tile([vel_ne[0], vel_ne[1], 0.0], (len(t), 1))
    pos = vel * (t - T0)[:, None]
    yaw = math.atan2(vel_ne[1], vel_ne[0]) + (math.pi if reversing else 0.0)
    return kinematic_truth(t, pos, vel, np.full(len(t), yaw))


def circle_truth(duration_s: float, radius_m: float = 6.0, speed_mps: float = 3.0) -> Truth:
    """Clockwise (seen from above) circle at constant speed, centre at the origin."""
    t = T0 + np.arange(0.0, duration_s, DT)
    w = speed_mps / radius_m
    ang = w * (t - T0)
    pos = np.column_stack((radius_m * np.cos(ang), radius_m * np.sin(ang), np.zeros(len(t))))
    vel = np.column_stack((-speed_mps * np.sin(ang), speed_mps * np.cos(ang), np.zeros(len(t))))
    return kinematic_truth(t, pos, vel, ang + math.pi / 2)


def parsed(out: ReceiverOutput, kind: str) -> list[tuple[float, pynmea2.NMEASentence]]:
    """(host time, parsed sentence) of every line of one sentence type."""
    return [(t, pynmea2.parse(s, check=True)) for t, s in out.lines if s[3:6] == kind]


def utc_of(msg: pynmea2.NMEASentence, day_start: float) -> float:
    ts = msg.timestamp
    return day_start + ts.hour * 3600 + ts.minute * 60 + ts.second + ts.microsecond * 1e-6


DAY_START = math.floor(T0 / 86400) * 86400


def test_every_line_parses_with_a_valid_checksum() -> None:
    cfg = GnssReceiverConfig(
        hdt=True, talker="GP", fix_schedule=(FixInterval(5, 7, FixQuality.NONE),)
    )
    out = simulate_receiver(straight_truth(10.0, (2.0, 1.0)), cfg)
    kinds = set()
    for _, s in out.lines:
        msg = pynmea2.parse(s, check=True)
        body, _, hh = s[1:].partition("*")
        assert int(hh, 16) == pynmea2.NMEASentence.checksum(body)
        assert msg.talker == "GP"
        kinds.add(msg.sentence_type)
    assert kinds == {"GGA", "RMC", "VTG", "GST", "ZDA", "HDT"}


def test_rtk_fixed_positions_match_the_truth_antenna() -> None:
    truth = circle_truth(60.0)
    out = simulate_receiver(truth)
    for _, gga in parsed(out, "GGA"):
        assert gga.gps_qual == FixQuality.RTK_FIXED
        t = utc_of(gga, DAY_START)
        h = float(gga.altitude) + float(gga.geo_sep)
        ned = lla_to_ned([gga.latitude, gga.longitude, h], ORIGIN)
        true = [np.interp(t, truth.t, c) for c in truth.pos_ant_ned_m.T]
        err = ned - true
        assert math.hypot(err[0], err[1]) < 0.05  # 1 cm per axis: 5 cm is > 3.5 sigma 2-D
        assert abs(err[2]) < 0.10
    rmc = parsed(out, "RMC")
    assert all(m.status == "A" and m.mode_indicator == "R" for _, m in rmc)


def test_position_noise_is_time_correlated_with_the_configured_sigma() -> None:
    out = simulate_receiver(straight_truth(600.0, (1.0, 0.0)))
    truth_ned = np.column_stack(
        ((out.t_utc - T0) * 1.0, np.zeros(len(out.t_utc)), np.zeros(len(out.t_utc)))
    )
    err = lla_to_ned(out.lla, ORIGIN) - truth_ned
    assert 0.006 < np.std(err[:, 0]) < 0.015
    assert 0.015 < np.std(err[:, 2]) < 0.035
    lag1 = np.corrcoef(err[:-1, 0], err[1:, 0])[0, 1]
    assert lag1 > 0.99  # tau 30 s at 10 Hz: a = 0.9967; white noise would give ~0


def test_white_position_noise_is_added_to_every_epoch_and_stated_by_gst() -> None:
    """``position_white_sigma_m``: independent from epoch to epoch (its steps show sqrt(2)
    of it, the wander's barely any), vertical twice; GST states the total; refused below 0."""
    truth = straight_truth(120.0, (1.0, 0.0))
    out = simulate_receiver(truth, GnssReceiverConfig(position_white_sigma_m=0.02))
    truth_ned = np.column_stack(
        ((out.t_utc - T0) * 1.0, np.zeros(len(out.t_utc)), np.zeros(len(out.t_utc)))
    )
    steps = np.diff(lla_to_ned(out.lla, ORIGIN) - truth_ned, axis=0)
    assert 0.025 < np.std(steps[:, 0]) < 0.032  # sqrt(2) x 2 cm
    assert 0.025 < np.std(steps[:, 1]) < 0.032
    assert 0.050 < np.std(steps[:, 2]) < 0.064
    gst = [m for _, m in parsed(out, "GST")]
    assert all(m.std_dev_latitude == pytest.approx(math.hypot(0.01, 0.02), abs=1e-3) for m in gst)
    assert all(m.std_dev_altitude == pytest.approx(math.hypot(0.025, 0.04), abs=1e-3) for m in gst)
    with pytest.raises(ValueError, match="position_white_sigma_m"):
        GnssReceiverConfig(position_white_sigma_m=-0.01)


def test_sog_and_cog_follow_the_velocity_and_reversing_keeps_the_course() -> None:
    fwd = simulate_receiver(straight_truth(20.0, (0.0, 2.0)))
    rev = simulate_receiver(
        straight_truth(20.0, (0.0, 2.0), reversing=True), GnssReceiverConfig(hdt=True)
    )
    for out in (fwd, rev):
        for _, rmc in parsed(out, "RMC"):
            assert abs(rmc.spd_over_grnd * KNOT_MPS - 2.0) < 0.1  # 2 cm/s per axis, > 3 sigma
            assert abs(rmc.true_course - 90.0) < 3.0
        for _, vtg in parsed(out, "VTG"):
            assert abs(float(vtg.spd_over_grnd_kmph) / 3.6 - 2.0) < 0.1
    headings = [float(m.heading) for _, m in parsed(rev, "HDT")]
    assert abs(np.mean(headings) - 270.0) < 0.1
    assert 0.05 < np.std(headings) < 0.3


def test_the_velocity_noise_can_be_set_for_every_fix_quality() -> None:
    """``velocity_sigma_mps``: Doppler's noise, the same RTK float or fixed (the noise table
    has 2 and 3 cm/s); refused below zero."""
    schedule = (FixInterval(0.0, 30.0, FixQuality.RTK_FLOAT),)
    truth = straight_truth(60.0, (0.0, 2.0))
    for sigma, lo, hi in ((0.05, 0.042, 0.058), (None, 0.015, 0.037)):
        cfg = GnssReceiverConfig(velocity_sigma_mps=sigma, fix_schedule=schedule)
        speeds = [
            rmc.spd_over_grnd * KNOT_MPS for _, rmc in parsed(simulate_receiver(truth, cfg), "RMC")
        ]
        half = len(speeds) // 2
        for part in (speeds[5:half], speeds[half:]):  # float, then fixed
            assert lo < np.std(part) < hi, (sigma, np.std(part))
    with pytest.raises(ValueError, match="velocity_sigma_mps"):
        GnssReceiverConfig(velocity_sigma_mps=-0.01)


def test_course_on_a_circle_is_tangent() -> None:
    truth = circle_truth(30.0)
    out = simulate_receiver(truth)
    for _, rmc in parsed(out, "RMC"):
        t = utc_of(rmc, DAY_START)
        vn, ve = (np.interp(t, truth.t, c) for c in truth.vel_ant_ned_mps[:, :2].T)
        expected = math.degrees(math.atan2(ve, vn)) % 360.0
        diff = (rmc.true_course - expected + 180.0) % 360.0 - 180.0
        assert abs(diff) < 2.0


def test_course_is_held_below_the_minimum_speed() -> None:
    truth = straight_truth(20.0, (1.0, 1.0))
    stop = truth.t - T0 > 10.0
    truth.vel_ant_ned_mps[stop] = 0.0
    out = simulate_receiver(truth)
    rmc = [m for _, m in parsed(out, "RMC")]
    still = [m for m in rmc if utc_of(m, DAY_START) - T0 > 10.2]
    assert still and all(abs(m.true_course - 45.0) < 3.0 for m in still)
    assert all(m.spd_over_grnd * KNOT_MPS < 0.1 for m in still)


def test_fix_quality_follows_the_schedule_and_outages_give_no_fix() -> None:
    schedule = (
        FixInterval(2.0, 4.0, FixQuality.RTK_FLOAT),
        FixInterval(4.0, 6.0, FixQuality.NONE),
        FixInterval(6.0, 8.0, FixQuality.DGNSS),
        FixInterval(8.0, 10.0, FixQuality.GNSS),
        FixInterval(10.0, 11.0, FixQuality.DEAD_RECKONING),
    )
    out = simulate_receiver(
        straight_truth(12.0, (1.0, 0.0)), GnssReceiverConfig(fix_schedule=schedule)
    )
    expected_mode = {4: "R", 5: "F", 2: "D", 1: "A", 6: "E", 0: "N"}
    rmc = {utc_of(m, DAY_START): m for _, m in parsed(out, "RMC")}
    gst = {utc_of(m, DAY_START): m for _, m in parsed(out, "GST")}
    for _, gga in parsed(out, "GGA"):
        t = utc_of(gga, DAY_START)
        rel = t - T0
        q = next(
            (s.quality for s in schedule if s.t_start_s <= rel < s.t_end_s), FixQuality.RTK_FIXED
        )
        assert gga.gps_qual == q
        assert rmc[t].mode_indicator == expected_mode[q]
        if q == FixQuality.NONE:
            assert gga.latitude == 0.0 and gga.lat == "" and gga.altitude is None
            assert rmc[t].status == "V" and rmc[t].spd_over_grnd is None
            assert gst[t].std_dev_latitude is None
        else:
            valid = q != FixQuality.DEAD_RECKONING  # NMEA: status V for mode E
            assert rmc[t].status == ("A" if valid else "V")
            assert gga.num_sats and float(gga.horizontal_dil) < 5
            corrected = q in (FixQuality.DGNSS, FixQuality.RTK_FLOAT, FixQuality.RTK_FIXED)
            assert (gga.age_gps_data != "") == corrected
            sigma = GnssReceiverConfig().noise[q].sigma_h_m
            assert gst[t].std_dev_latitude == pytest.approx(sigma, abs=1e-3)


def test_dead_reckoning_carries_the_last_fix_on_at_its_velocity_up_to_the_limit() -> None:
    """u-blox's drLimit: through an outage a receiver without sensors sends its last fix
    moved on at its last velocity, course and all, as DEAD_RECKONING, for up to the limit;
    then no fix. On a circle the carried positions leave the turn along its tangent."""
    cfg = GnssReceiverConfig(
        fix_schedule=(FixInterval(4.0, 8.0, FixQuality.NONE),), dead_reckoning_limit_s=2.0
    )
    out = simulate_receiver(circle_truth(10.0), cfg)
    rel = out.t_utc - T0
    last = int(np.flatnonzero(rel < 4.0)[-1])
    carried = out.quality == FixQuality.DEAD_RECKONING
    dt = rel[carried] - rel[last]
    assert carried.sum() == 20 and np.all((dt > 0.0) & (dt <= 2.0 + 1e-9))
    assert np.all(out.quality[(rel >= 4.0) & (rel < 8.0) & ~carried] == FixQuality.NONE)
    assert (out.quality[(rel >= 4.0) & (rel < 8.0)] == FixQuality.NONE).sum() == 20
    assert np.array_equal(out.vel_ne_mps[carried], np.tile(out.vel_ne_mps[last], (20, 1)))
    ned = lla_to_ned(out.lla, ORIGIN)
    expected = ned[last, :2] + out.vel_ne_mps[last] * dt[:, None]
    assert np.allclose(ned[carried, :2], expected, atol=1e-3)
    assert np.allclose(ned[carried, 2], ned[last, 2], atol=1e-3)
    rmc = {round(utc_of(m, DAY_START) - T0, 2): m for _, m in parsed(out, "RMC")}
    assert all(rmc[round(r, 2)].mode_indicator == "E" for r in rel[carried])


def test_epochs_on_whole_multiples_and_receive_times_after_latency() -> None:
    cfg = GnssReceiverConfig(
        rate_hz=20.0, latency_s=0.05, latency_jitter_s=0.002, host_clock_offset_s=0.5
    )
    out = simulate_receiver(straight_truth(5.0, (1.0, 0.0)), cfg)
    assert np.allclose(np.round(out.t_utc * 20.0), out.t_utc * 20.0, atol=1e-6)
    assert out.t_utc[0] + 0.5 >= T0 and out.t_utc[0] + 0.5 - T0 < 0.05  # host 0.5 s ahead
    byte_s = 10.0 / 115200
    prev = -math.inf
    for host_t, s in out.lines:
        assert host_t > prev  # in order, later sentences of an epoch later
        prev = host_t
        msg = pynmea2.parse(s)
        if hasattr(msg, "timestamp") and msg.timestamp is not None:
            epoch = utc_of(msg, DAY_START)
            delay = host_t - 0.5 - epoch
            assert 0.05 + (len(s) + 2) * byte_s - 1e-6 <= delay < 0.05 + 0.002 + 0.05


def test_a_slow_serial_link_queues_epochs_behind_each_other() -> None:
    cfg = GnssReceiverConfig(baud=19200, hdt=True)  # ~350 bytes an epoch: 180 ms per 100 ms
    out = simulate_receiver(straight_truth(5.0, (1.0, 0.0)), cfg)
    byte_s = 10.0 / 19200
    gaps = np.diff([t for t, _ in out.lines])
    lengths = np.array([len(s) + 2 for _, s in out.lines[1:]])
    assert np.all(gaps >= lengths * byte_s - 1e-6)  # one line at a time on the wire
    assert out.lines[-1].host_t - out.t_utc[-1] > 3.0  # the backlog grows, as on a real UART


def test_rates_that_do_not_fit_hhmmss_ss_are_refused() -> None:
    with pytest.raises(ValueError, match="rate_hz"):
        GnssReceiverConfig(rate_hz=3.0)
    with pytest.raises(ValueError, match="PPS"):
        GnssReceiverConfig(fix_schedule=(FixInterval(0, 1, FixQuality.PPS),))


def test_same_seed_same_output() -> None:
    truth = circle_truth(5.0)
    assert simulate_receiver(truth).lines == simulate_receiver(truth).lines
    assert (
        simulate_receiver(truth).lines != simulate_receiver(truth, GnssReceiverConfig(seed=1)).lines
    )
