"""The imitation phase of a value-based training run, then its first validation.

ORCA demonstrations, the value fit and (information ``learned``) the state predictor's fit,
resumable per epoch; the validation after them opens the RL phase's state.
"""

from __future__ import annotations

import json
import math

import torch

from socialnav._progress import progress_bar
from socialnav.train.episodes import validate
from socialnav.train.optim import TrainingDiverged, load_optimizer_state, make_optimizer, optimizer_state
from socialnav.train.run_directory import check_record
from socialnav.train.value.run import ValueRun
from socialnav.train.value.settings import resume_diff
from socialnav.train.value.state import TrainState
from socialnav.train.worlds import MultiWorld


def imitate_then_validate(run: ValueRun) -> TrainState:
    """Imitation (when the settings ask for some), then the validation after it and its curves row.

    Args:
        run: a fresh run (no ``last.pt``).

    Returns:
        The RL phase's initial state: episode 0, that validation as the best and the last.
    """
    il = run.settings.imitation
    if il.episodes > 0 and il.epochs > 0:
        il_loss, predictor_losses = run_imitation(run)
    else:
        il_loss, predictor_losses = math.nan, []
    val = validate(run.policy, run.val_world, run.oracle, run.success_reward)
    run.say(
        f"after imitation: validation success {val['success']:.3f} collision {val['collision']:.3f} "
        f"timeout {val['timeout']:.3f} nav_time {val['nav_time']:.2f}"
    )
    state = TrainState.fresh(run, {**val, "episode": 0})
    run.curves.write(
        {
            "phase": "il",
            "episode": 0,
            "loss": il_loss,
            "val_success": val["success"],
            "val_collision": val["collision"],
            "val_timeout": val["timeout"],
            "val_nav_time": val["nav_time"],
            "predictor_loss": predictor_losses[-1] if predictor_losses else math.nan,
            "gradient_steps": 0,
            "transitions": 0,
            "wall_time": state.wall(run),
        }
    )
    return state


def run_imitation(run: ValueRun) -> tuple[float, list[float]]:
    """Imitation learning, resumable.

    The demonstrations are kept in ``il_demos.npz`` once collected, and ``il_state.pt`` holds the
    network, optimizer and sampling generator after every epoch. A complete ``il.pt`` is reused as
    it is. With a state predictor (information ``learned``), it is fitted on the demonstrations'
    human transitions after the value network (as RGL does during imitation), in one block: a kill
    during that block repeats only the predictor's fit.

    Args:
        run: the run (its network, and predictor, are trained in place).

    Returns:
        The last epoch's value loss and the predictor's losses per epoch.

    Raises:
        TrainingDiverged: the loss became NaN/inf (``il_state.pt`` keeps the last good epoch).
    """
    from socialnav.policies.learned import load_checkpoint, save_checkpoint
    from socialnav.policies.native import NativePolicy
    from socialnav.train.value.imitation import (
        collect_demonstrations,
        fit_values,
        load_demonstrations,
        save_demonstrations,
    )

    settings, preset, out, say, config = run.settings, run.preset, run.out, run.say, run.config
    policy_name, name, net, device, seeds = run.policy_name, run.name, run.net, run.device, run.seeds
    il, rl = settings.imitation, settings.rl
    il_path, state_path, demos_path = out / "il.pt", out / "il_state.pt", out / "il_demos.npz"
    if il_path.exists():  # imitation finished before the interruption
        ck = load_checkpoint(il_path, name, map_location=device)
        check_record(ck.config, config, out, resume_diff)
        net.load_state_dict(ck.model.state_dict())
        if run.predictor is not None and ck.predictor is not None:
            run.predictor.load_state_dict(ck.predictor.state_dict())
        done = ck.extra.get("il_losses") or []
        say(f"imitation: reusing {il_path}")
        return (done[-1] if done else math.nan), list(ck.extra.get("predictor_losses") or [])
    config_json = json.dumps(config, sort_keys=True)
    if demos_path.exists():
        demos, saved = load_demonstrations(demos_path)
        check_record(json.loads(saved), config, out, resume_diff)
        say(f"imitation: reusing {demos.episodes} teacher episodes from {demos_path}, {len(demos)} states")
    else:
        teacher = NativePolicy(
            "orca", safety_space=il.teacher_safety_space, orca=preset.world.orca, threads=preset.world.threads
        )
        world = MultiWorld(preset, run.n_humans, settings.collection_batch, "train", seeds["scenario_start"])
        world.reset()
        bar = progress_bar(il.episodes, 0, desc=f"{policy_name} imitation: ORCA demos", enabled=run.progress)
        try:
            demos = collect_demonstrations(
                world,
                teacher,
                il.episodes,
                rl.gamma,
                run.success_reward,
                progress=lambda k: bar.update(k) if k else None,
                policy=run.policy,
            )
        finally:
            bar.close()
            world.close()  # its native threads are not needed after the demonstrations
        save_demonstrations(demos_path, demos, config_json)
        say(f"imitation: {demos.episodes} teacher episodes {demos.outcomes}, {len(demos)} states")

    generator = torch.Generator().manual_seed(seeds["sampling"] ^ 0x1A1A)
    optimizer = make_optimizer(net.parameters(), il.lr, device)
    losses: list[float] = []
    if state_path.exists():
        ck = load_checkpoint(state_path, name, map_location=device)
        check_record(ck.config, config, out, resume_diff)
        net.load_state_dict(ck.model.state_dict())
        load_optimizer_state(optimizer, ck.extra["optimizer"])
        generator.set_state(ck.extra["generator"])
        losses = list(ck.extra["il_losses"])
        say(f"imitation: resuming at epoch {len(losses)} of {il.epochs}")
    bar = progress_bar(il.epochs, len(losses), desc=f"{policy_name} imitation: fit", enabled=run.progress)

    def on_epoch(epoch: int, loss: float) -> None:
        losses.append(loss)
        extra = {
            "phase": "imitation",
            "il_losses": losses,
            "optimizer": optimizer_state(optimizer),
            "generator": generator.get_state(),
        }
        save_checkpoint(state_path, policy_name, net, config=config, extra=extra)
        bar.update(1)
        # refresh=False: drawn at the bar's own pace (in a log file: once a minute), not at every epoch
        bar.set_postfix(loss=f"{loss:.4g}", refresh=False)

    try:
        fit_values(
            run.policy, demos, il.epochs, il.batch_size, generator, optimizer, on_epoch, len(losses),
            compiled=settings.compile,
        )
    except FloatingPointError as err:
        kept = (f"{state_path} keeps the last good epoch" if state_path.exists()
                else "no epoch finished (lower imitation.lr?)")
        raise TrainingDiverged(f"{err}; {kept}") from None
    finally:
        bar.close()
    predictor_losses: list[float] = []
    if run.predictor is not None and run.predictor_optimizer is not None:
        from socialnav.train.value.imitation import fit_predictor

        predictor_losses = fit_predictor(
            run.predictor,
            run.predictor_optimizer,
            demos,
            il.epochs,
            il.batch_size,
            preset.world.dt,
            torch.Generator().manual_seed(seeds["sampling"] ^ 0x9E3D),
            device,
        )
        if predictor_losses:
            say(f"imitation: state predictor position MSE {predictor_losses[-1]:.4g} m² ({il.epochs} epochs)")
    extra = {"phase": "imitation", "il_losses": losses, "predictor_losses": predictor_losses}
    save_checkpoint(il_path, policy_name, net, config=config, extra=extra, predictor=run.predictor)
    # il.pt is complete: the intermediate files are no longer needed (the demonstrations are large).
    state_path.unlink(missing_ok=True)
    demos_path.unlink(missing_ok=True)
    return (losses[-1] if losses else math.nan), predictor_losses
