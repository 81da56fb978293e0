"""heliostep.cosim.fmi: the one FMI layer, its error path, and the FMUs' life cycle."""

import ctypes
import ctypes.util
import gc

import numpy as np
import pytest

from heliostep.cosim.fmi import FMIError, ModelExchangeInstance, read_fmu
from heliostep.errors import InputError


class _MallInfo2(ctypes.Structure):
    """glibc's ``struct mallinfo2``."""

    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks")
    ] + [("keepcost", ctypes.c_size_t)]


_LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")


def _allocated_bytes() -> int:
    """The bytes malloc holds for the program, in every thread's arena and mapped blocks (glibc's mallinfo2),
    once the unreachable Python objects (ctypes' among them) are collected."""
    gc.collect()
    mallinfo2 = _LIBC.mallinfo2
    mallinfo2.restype = _MallInfo2
    info = mallinfo2()
    return int(info.uordblks + info.hblkhd)


def _one_life(info):
    inst = ModelExchangeInstance(info, "cycle", {"K_current": 80.0})
    inst.setup_experiment(0.0)
    inst.enter_initialization_mode()
    inst.exit_initialization_mode()
    inst.enter_continuous_time_mode()
    inst.set_time(0.001)
    inst.get_derivatives()
    inst.terminate()
    inst.reset()
    inst.setup_experiment(0.0)
    inst.enter_initialization_mode()
    inst.exit_initialization_mode()
    inst.terminate()
    inst.free()


@pytest.mark.skipif(not hasattr(_LIBC, "mallinfo2"), reason="needs glibc's mallinfo2")
def test_thousand_life_cycles_do_not_crash_or_grow_memory(fmu_paths):
    """A thousand life cycles of an instance: none crashes, and the bytes malloc holds (the FMU's and fmpy's
    allocations among them) grow by less than 64 bytes per cycle, so a leak of a hundred bytes per cycle or
    more fails. Measured as allocated bytes, not resident pages, after a thousand cycles that level off what
    grows while caches fill (by about 30 bytes per cycle, then less and less), each figure the least of five
    readings: another thread's passing allocations (pytest-xdist's) only add to a reading, so the machine's
    load does not move it."""
    info = read_fmu(fmu_paths["StepperMotor"])
    for _ in range(1000):
        _one_life(info)
    before = min(_allocated_bytes() for _ in range(5))
    for _ in range(1000):
        _one_life(info)
    growth = min(_allocated_bytes() for _ in range(5)) - before
    assert growth < 64 * 1000, f"malloc's bytes grew by {growth} over 1000 life cycles ({growth / 1000:.0f} per cycle)"


@pytest.fixture
def motor(fmu_paths):
    inst = ModelExchangeInstance(read_fmu(fmu_paths["StepperMotor"]), "motor")
    yield inst
    inst.free()


def test_invalid_value_reference_is_an_fmi_error_with_the_log(motor):
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    motor.exit_initialization_mode()
    with pytest.raises(FMIError) as error:
        motor.get_real([10_000])
    assert error.value.function == "fmi2GetReal" and error.value.status == "fmi2Error"
    assert "invalid value reference 10000" in str(error.value)
    # fmi2Error puts the instance in the error state: values can still be read, nothing set
    assert motor.get_real(motor.value_references(["i_a"]))[0] == 0.0
    with pytest.raises(FMIError, match="fmi2SetReal: not allowed in error") as error:
        motor.set_real(motor.value_references(["i_a_ref"]), [1.0])
    assert "invalid value reference" not in str(error.value)  # no stale message
    motor.reset()  # allowed in the error state, and usable again afterwards
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    with pytest.raises(FMIError, match="fmi2SetReal: invalid value reference 10000"):
        motor.set_real([10_000], [1.0])


def test_calls_in_the_wrong_state_are_fmi_errors(motor):
    with pytest.raises(FMIError, match="fmi2GetDerivatives: not allowed in instantiated"):
        motor.get_derivatives()
    with pytest.raises(FMIError, match="fmi2ExitInitializationMode: not allowed"):
        motor.exit_initialization_mode()
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    motor.exit_initialization_mode()
    motor.enter_continuous_time_mode()
    with pytest.raises(FMIError, match="fmi2NewDiscreteStates: not allowed in continuous-time mode"):
        motor.update_discrete_states()
    with pytest.raises(FMIError, match="parameter L can only be set"):
        motor.set_real(motor.value_references(["L"]), [1e-3])
    assert motor.mode == "error"
    with pytest.raises(FMIError, match="fmi2EnterEventMode: not allowed in error"):
        motor.enter_event_mode()
    motor.terminate()  # allowed from the error state
    motor.reset()
    with pytest.raises(FMIError, match="tau is computed by the model"):
        motor.set_real(motor.value_references(["tau"]), [1.0])


def test_tunable_parameter_changes_the_model_in_event_mode(motor):
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    motor.set_real(motor.value_references(["i_a_ref"]), [5.5])
    motor.exit_initialization_mode()
    # from rest the chopper saturates: di/dt = dV / L
    assert motor.get_derivatives()[0] == pytest.approx(3.1 / 1.8e-3)
    motor.set_parameters({"V_supply": 6.2})
    assert motor.get_derivatives()[0] == pytest.approx(6.2 / 1.8e-3)


def test_unknown_parameter_lists_the_valid_names(fmu_paths):
    info = read_fmu(fmu_paths["PanelMechanics"])
    with pytest.raises(InputError) as error:
        ModelExchangeInstance(info, "mech", {"J_rotor": 1e-4})
    message = str(error.value)
    assert "J_rotor" in message and "PanelMechanics.fmu" in message
    for name in ("J_p", "J_m", "b", "r", "s"):
        assert name in message


def test_start_values_follow_their_parameters(fmu_paths):
    info = read_fmu(fmu_paths["PanelMechanics"])
    with ModelExchangeInstance(info, "mech", {"theta_p_start": 0.25, "theta_start": 1.0}) as inst:
        inst.setup_experiment(0.0)
        inst.enter_initialization_mode()
        inst.exit_initialization_mode()
        np.testing.assert_allclose(inst.get_states(), [0.25, 0.0])
        assert inst.reader(["theta"])()[0] == pytest.approx(1.0)


def test_read_fmu_rejects_what_is_not_fmi2_model_exchange(tmp_path):
    with pytest.raises(InputError, match="FMU file not found"):
        read_fmu(tmp_path / "missing.fmu")
    bogus = tmp_path / "bogus.fmu"
    bogus.write_text("not a zip")
    with pytest.raises(InputError, match="bogus.fmu: not a readable FMU"):
        read_fmu(bogus)


def test_read_fmu_rejects_a_co_simulation_only_fmu(fmu_paths, tmp_path):
    import zipfile

    cs_only = tmp_path / "CoSimOnly.fmu"
    with zipfile.ZipFile(fmu_paths["StepperMotor"]) as source, zipfile.ZipFile(cs_only, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b"<ModelExchange", b"<CoSimulation").replace(b"</ModelExchange", b"</CoSimulation")
            target.writestr(item, data)
    with pytest.raises(InputError, match="CoSimOnly.fmu: the FMU does not support Model Exchange"):
        read_fmu(cs_only)


def test_rejected_set_real_writes_nothing_and_leaves_no_stale_value(motor):
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    motor.exit_initialization_mode()
    before = motor.get_derivatives()
    i_a_ref, tau = motor.value_references(["i_a_ref", "tau"])
    # a valid reference first, then a computed one: the whole call is refused, i_a_ref unchanged
    with pytest.raises(FMIError, match="tau is computed by the model"):
        motor.set_real([i_a_ref, tau], [5.5, 1.0])
    assert motor.get_real([i_a_ref])[0] == 0.0
    np.testing.assert_array_equal(motor.get_derivatives(), before)  # recomputed, not stale
    motor.reset()
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    motor.exit_initialization_mode()
    with pytest.raises(FMIError, match="invalid value reference 10000"):
        motor.set_real([i_a_ref, 10_000], [5.5, 1.0])
    assert motor.get_real([i_a_ref])[0] == 0.0
    # after a valid set the derivatives follow the new input (the cache was invalidated)
    motor.reset()
    motor.setup_experiment(0.0)
    motor.enter_initialization_mode()
    motor.set_real([i_a_ref], [5.5])
    motor.exit_initialization_mode()
    assert motor.get_derivatives()[0] == pytest.approx(3.1 / 1.8e-3)
