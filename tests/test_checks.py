import numpy as np
import pytest

from activeperc_env.checks import MAX_SEED, check_actions, check_seed, is_seed


def test_seeds_are_ints_in_range_for_as_many_rooms():
    assert check_seed(np.int64(5)) == 5 and type(check_seed(np.int64(5))) is int
    assert is_seed(MAX_SEED) and not is_seed(MAX_SEED, rooms=2) and is_seed(MAX_SEED - 1, rooms=2)
    for bad in (-1, MAX_SEED + 1, 1.0, True, "3", None):
        with pytest.raises(ValueError, match=r"my_seed=.* is invalid: expected an int in \[0, 2\*\*63 - 1\]"):
            check_seed(bad, "my_seed")
    with pytest.raises(ValueError, match=r"seed=-1 is invalid: room i gets seed \+ i, so with 4 rooms"):
        check_seed(np.int64(-1), rooms=4)


def test_actions_are_one_int_of_the_space_per_room():
    assert check_actions(2, 1, 3, "mover").tolist() == [2]
    assert check_actions(np.array([0, 2]), 2, 3, "mover").dtype == np.int64
    assert check_actions([], 0, 3, "mover").shape == (0,)
    with pytest.raises(ValueError, match=r"mover action\(s\) \[1\] invalid: expected 2 ints in its action space"):
        check_actions([1], 2, 3, "mover")
    with pytest.raises(ValueError, match=r"mover action\(s\) True invalid: expected an int"):
        check_actions(True, 1, 3, "mover")
    with pytest.raises(ValueError, match=r"looker action 3 of room 1 is outside its action space Discrete\(3\) \('a'"):
        check_actions([0, 3], 2, 3, "looker", ("a", "b", "c"))
    with pytest.raises(ValueError, match=r"^mover action -1 is outside"):
        check_actions(-1, 1, 3, "mover")


def test_one_agents_step_takes_an_int_and_a_vector_env_an_array():
    assert check_actions(np.int64(1), 1, 3, "mover", scalar=True).tolist() == [1]
    with pytest.raises(ValueError, match=r"mover action\(s\) \[2\] invalid: expected an int"):
        check_actions([2], 1, 3, "mover", scalar=True)
    assert check_actions([2], 1, 3, "mover", scalar=False).tolist() == [2]
    with pytest.raises(ValueError, match=r"mover action\(s\) 2 invalid: expected 1 ints"):
        check_actions(2, 1, 3, "mover", scalar=False)
