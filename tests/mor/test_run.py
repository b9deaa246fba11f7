"""The mor --spec, mor --robot and saturate verbs on the samples."""

from hound_id.mor.region import operating_region
from hound_id.mor.robot import load_robot
from hound_id.mor.run import motor_regions, robot_regions_of, saturate_commands
from hound_id.mor.saturate_log import saturate_log
from hound_id.tables import read_table
from tests.conftest import MOTOR, ROBOT, SAMPLES

COMMANDS = SAMPLES / "commands" / "hound_like_running.csv"


def test_a_spec_without_envelope_has_the_spec_sheets_region():
    run = motor_regions(MOTOR)
    assert not run.measured and run.report()["spec_sheet"] is None
    assert run.region.to_dict() == operating_region(run.spec).to_dict() == run.sheet.to_dict()


def test_robot_warnings_come_before_the_regions():
    seen = []
    run = robot_regions_of(ROBOT, on_warnings=seen.append)
    assert seen == [run.warnings] and len(run.regions.joints) == len(run.robot.joints)


def test_streamed_saturation_equals_the_whole_log_and_keeps_rows_only_for_a_plot():
    run = saturate_commands(COMMANDS, ROBOT, plot=True)
    whole = saturate_log(load_robot(ROBOT), read_table(COMMANDS), source=str(COMMANDS))
    assert run.summary.to_dict() == whole.to_dict()
    assert run.summary.sample is not None and run.figure() is not None
    assert saturate_commands(COMMANDS, ROBOT).figure() is None
