"""Read a Parapet flight.ulg with pyulog and check vehicle_status.nav_state against PX4's numbers.

usage: check_ulog_modes.py FILE EXPECTED
EXPECTED: comma-separated PX4 nav_state values that must appear in this order among the
log's nav_state changes (e.g. "2,5,18": POSCTL, then AUTO_RTL, then AUTO_LAND).
Also checks every record: nav_state is PX4's number for the guidance mode logged beside it
(`parapet_mode`), from PX4's msg/VehicleStatus.msg (written here independently of the Rust
mapping), and arming_state is 2 (armed) exactly when the guidance mode is not Off.
Exit 0 when every check passes; prints what failed otherwise (exit 1).
"""
import sys

from pyulog import ULog

# PX4 VehicleStatus.msg NAVIGATION_STATE_*.
MANUAL, POSCTL, AUTO_MISSION, AUTO_LOITER, AUTO_RTL = 0, 2, 3, 4, 5
DESCEND, OFFBOARD, AUTO_TAKEOFF, AUTO_LAND = 12, 14, 17, 18
# parapet_mode codes (GuidanceMode::ALL order) -> the PX4 state; None: the selected mode's.
GUIDANCE = {
    0: ("Off", None),
    1: ("Ground", None),
    2: ("Hold", None),
    3: ("Takeoff", AUTO_TAKEOFF),
    4: ("Mission", AUTO_MISSION),
    5: ("Brake", AUTO_LOITER),
    6: ("Land", AUTO_LAND),
    7: ("NoFix", DESCEND),
    8: ("Manual", MANUAL),
    9: ("Assist", POSCTL),
    10: ("Offboard", OFFBOARD),
    11: ("Return", AUTO_RTL),
}
SELECTED = {MANUAL, POSCTL, AUTO_MISSION, AUTO_LOITER, AUTO_RTL, OFFBOARD, AUTO_LAND}

path, expected = sys.argv[1], [int(x) for x in sys.argv[2].split(",") if x]
u = ULog(path)
st = next(d.data for d in u.data_list if d.name == "vehicle_status")
errors = []
for i, (nav, mode, arm) in enumerate(zip(st["nav_state"], st["parapet_mode"], st["arming_state"])):
    if mode not in GUIDANCE:
        errors.append(f"record {i}: parapet_mode {mode} is no guidance mode")
        break
    name, want = GUIDANCE[mode]
    if want is not None and nav != want:
        errors.append(f"record {i}: guidance {name}, nav_state {nav}, PX4's is {want}")
        break
    if want is None and nav not in SELECTED:
        errors.append(f"record {i}: guidance {name} (waiting), nav_state {nav} is no selectable mode")
        break
    if (arm == 2) != (name != "Off") or arm not in (1, 2):
        errors.append(f"record {i}: guidance {name}, arming_state {arm}")
        break
changes = []
for nav in st["nav_state"]:
    if not changes or changes[-1] != nav:
        changes.append(int(nav))
it = iter(changes)
if not all(any(c == e for c in it) for e in expected):
    errors.append(f"nav_state changes {changes} do not contain {expected} in order")
print(f"{path}: nav_state changes {changes}")
if errors:
    print("\n".join(errors))
    sys.exit(1)
