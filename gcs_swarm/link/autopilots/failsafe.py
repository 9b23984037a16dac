"""What a flight asks every autopilot to do when the ground station goes silent, in the ground station's own
terms; each dialect's `flight_params` turns it into its parameters (ArduCopter FS_GCS_* and GUID_TIMEOUT,
PX4 COM_OF_LOSS_T, COM_OBL_RC_ACT, NAV_DLL_ACT, COM_DL_LOSS_T)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FailsafeSettings:
    """The mission's safety.gcs_failsafe and safety.dead_gcs timings (docs/reliability.md)."""

    action: str  # "brake" | "land" | "rtl" | "off": what a vehicle does when it gives up the GCS
    gcs_loss_s: float  # s without the ground station's HEARTBEAT before that action (FS_GCS_TIMEOUT)
    guided_timeout_s: float  # s an ArduCopter flies its last attitude target, then levels (GUID_TIMEOUT)
    offboard_loss_s: float  # s a PX4 flies its last OFFBOARD target before the action (COM_OF_LOSS_T)
