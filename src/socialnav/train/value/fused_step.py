"""A whole RL gradient step as one compiled graph (training setting ``compile: true``).

The eager gradient step of these small value networks is mostly host work: ≈ 260 operator calls
for the forward pass alone, the autograd engine, the optimizer (docs/training_speed.md measures it).
Compiling the loss alone (``train/value/rl.py: replay_td_loss(compiled=True)``) removes most of the
operator calls, but every step still goes through Dynamo's guards, the autograd engine for the
backward pass and a separate Adam call. Here the step is traced once into one graph of flat tensors
— replay-memory gather, agent-centric transforms of s and s′, the target network's forward pass,
the online forward and backward passes (``torch.func.grad_and_value``), and Adam's update written
out (Kingma & Ba, "Adam: A Method for Stochastic Optimization", ICLR 2015, Algorithm 1, in
PyTorch's form: ``torch.optim.Adam`` with ``eps`` added after the bias-corrected square root) — and
compiled by Inductor. A call passes the tensors explicitly: there are no guards to evaluate, no
autograd graph, no optimizer call; the graph updates the parameters and the optimizer's own state
tensors in place, so checkpoints, ``optimizer.state_dict()`` and a resume (compiled or eager) see
the same state as after ``optimizer.step()``.

What the trace fixes, and so what a step object must not see change: the minibatch size, the
memory's tensors (preallocated; pushes write into them), the parameter tensors of both networks
(``load_state_dict`` copies into them), γ, dt, the learning rate and Adam's betas and eps. A network
whose value has data-dependent control flow (CADRL's crowd-less rows, LSTM-RL's packed sequences)
does not trace into one graph: :meth:`FusedTDStep.build` then says why, and the trainer compiles the
loss alone instead.

On a CUDA device the compiled step is also recorded once as a CUDA graph and replayed for every
step: the ≈ 30 kernels of a step then cost one launch instead of ≈ 1.8 ms of host work for a
minibatch of 100 (docs/training_speed.md). The graph replays exactly the kernels the compiled
step runs, so its results are bit-identical to calling the compiled step (tested on a GPU); the
recording's warm-up calls run on copies of the state they change, which are then restored, so the
recording changes no parameter, moment or step counter.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.fx.experimental.proxy_tensor import make_fx

from socialnav.train.optim import shared_step_counters, use_inductor_cache_of_these_kernels
from socialnav.train.value.memory import ReplayMemory, Transitions
from socialnav.train.value.rl import td_targets

_MEMORY_FIELDS = (
    "robot",
    "humans",
    "mask",
    "reward",
    "next_robot",
    "next_humans",
    "next_mask",
    "done",
    "target",
)


class _Value(nn.Module):
    """``network.value`` as a module's forward.

    So that ``torch.func.functional_call`` can run it with parameters passed in.
    """

    def __init__(self, network: nn.Module) -> None:
        super().__init__()
        self.network = network

    def forward(self, joint_state: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return self.network.value(joint_state, mask)


class FusedTDStep:
    """``step(idx)``: one TD gradient step on memory slots ``idx`` in one compiled graph.

    The loss of ``train/value/rl.py: td_loss`` and Adam's update of ``optimizer``'s parameters; returns
    the minibatch loss (before the update; a 0-d tensor, not synchronised).

    Build it with :meth:`build`, after the optimizer's state is loaded (a resume).
    """

    def __init__(
        self,
        policy,
        target_net: nn.Module,
        memory: ReplayMemory,
        optimizer: torch.optim.Optimizer,
        gamma: float,
        dt: float,
        batch_size: int,
        fixed_targets: bool = False,
        cuda_graph: bool = True,
    ) -> None:
        """Prepares the step (compiled by :meth:`build`).

        Args:
            policy: the ValuePolicy (its agent-centric transform and network).
            target_net: the target network.
            memory: the replay memory the indices address.
            optimizer: the network's fused Adam (one parameter group).
            gamma: discount factor.
            dt: time step [s].
            batch_size: minibatch size (the graph is compiled for it).
            fixed_targets: use the targets stored with the transitions (rl.td_targets rgl_repo).
            cuda_graph: on CUDA, replay the step as a CUDA graph.

        Raises:
            ValueError: not one parameter group of a fused-capable Adam.
        """
        groups = optimizer.param_groups
        g = groups[0]
        if not isinstance(optimizer, torch.optim.Adam) or len(groups) != 1:
            raise ValueError("the fused step implements one parameter group of torch.optim.Adam")
        unsupported = [k for k in ("amsgrad", "maximize", "decoupled_weight_decay") if g.get(k)]
        if g.get("weight_decay", 0) != 0:
            unsupported.append("weight_decay")
        if isinstance(g["lr"], torch.Tensor):
            unsupported.append("tensor lr")
        if unsupported:
            raise ValueError(f"the fused step does not implement Adam's {', '.join(unsupported)}")
        self.policy = policy
        self.network: nn.Module = policy.network
        self.target_net = target_net
        self.memory = memory
        self.optimizer = optimizer
        self.batch_size = int(batch_size)
        self.fixed_targets = bool(fixed_targets)
        self._gamma, self._dt = float(gamma), float(dt)
        self._lr, (self._beta1, self._beta2), self._eps = float(g["lr"]), g["betas"], float(g["eps"])
        self._params: list[torch.Tensor] = list(g["params"])
        self._value, self._target_value = _Value(self.network), _Value(target_net)
        online = dict(self._value.named_parameters())
        if [id(p) for p in online.values()] != [id(p) for p in self._params]:
            raise ValueError("the optimizer must hold exactly the policy network's parameters, in order")
        # the names functional_call takes, in the order of the graph's inputs (_ensure_state)
        self._param_names = list(online)
        self._buffer_names = [n for n, _ in self._value.named_buffers()]
        self._target_names = [n for n, _ in self._target_value.named_parameters()] + [
            n for n, _ in self._target_value.named_buffers()
        ]
        self._state_seen: object = None
        self._inputs: list[torch.Tensor] = []
        self._compiled = None
        self._use_graph = bool(cuda_graph) and memory.device.type == "cuda"
        self._graph: torch.cuda.CUDAGraph | None = None
        self._graph_idx: torch.Tensor | None = None
        self._graph_loss: torch.Tensor | None = None

    # -- construction -------------------------------------------------------------------------------

    @classmethod
    def build(cls, *args, **kwargs) -> tuple[FusedTDStep | None, str | None]:
        """Builds and compiles a step, or says why the network's value does not trace into one graph.

        Args:
            *args: the constructor's arguments.
            **kwargs: the constructor's keyword arguments.

        Returns:
            ``(step, None)``, or ``(None, reason)``.
        """
        step = cls(*args, **kwargs)
        try:
            step._compile()
        except Exception as err:  # noqa: BLE001 - any tracing failure means: use the compiled loss
            first_line = str(err).splitlines()[0] if str(err) else ""
            return None, f"{type(err).__name__}: {first_line}"
        return step, None

    def _ensure_state(self) -> None:
        """Creates Adam's state if it has none yet, and gathers the graph's inputs.

        The state is what ``torch.optim.Adam(fused=True)`` creates on its first step (zero moments,
        a float32 step counter per parameter). The step counters become 0-d views of one tensor
        (``shared_step_counters``, as for ``AdamSteps``), so the graph updates them with one add.
        """
        state = self.optimizer.state
        for p in self._params:
            if p not in state or not state[p]:
                state[p] = {
                    "step": torch.zeros((), dtype=torch.float32, device=p.device),
                    "exp_avg": torch.zeros_like(p, memory_format=torch.preserve_format),
                    "exp_avg_sq": torch.zeros_like(p, memory_format=torch.preserve_format),
                }
        per_param = [state[p] for p in self._params]
        for s in per_param:  # the graph is compiled for float32 counters, whatever a loaded state holds
            s["step"] = s["step"].to(torch.float32)
        steps = shared_step_counters(per_param)
        self._inputs = [
            *(p.detach() for p in self._params),
            *(b.detach() for b in self.network.buffers()),
            *(t.detach() for t in self.target_net.parameters()),
            *(b.detach() for b in self.target_net.buffers()),
            *(getattr(self.memory, f) for f in _MEMORY_FIELDS),
            *(s["exp_avg"] for s in per_param),
            *(s["exp_avg_sq"] for s in per_param),
            steps,
        ]
        self._state_seen = state

    def _step_function(self):
        n_p, n_b = len(self._param_names), len(self._buffer_names)
        n_t = len(self._target_names)
        policy, gamma, dt = self.policy, self._gamma, self._dt
        lr, beta1, beta2, eps = self._lr, self._beta1, self._beta2, self._eps
        fixed = self.fixed_targets
        names, buffer_names, target_names = self._param_names, self._buffer_names, self._target_names
        value, target_value = self._value, self._target_value

        def step(idx: torch.Tensor, *flat: torch.Tensor) -> tuple[torch.Tensor]:
            params = list(flat[:n_p])
            buffers = dict(zip(buffer_names, flat[n_p : n_p + n_b], strict=True))
            at = n_p + n_b
            target = dict(zip(target_names, flat[at : at + n_t], strict=True))
            at += n_t
            batch = Transitions(*(t[idx] for t in flat[at : at + len(_MEMORY_FIELDS)]))
            at += len(_MEMORY_FIELDS)
            exp_avgs, exp_avg_sqs, steps = flat[at : at + n_p], flat[at + n_p : at + 2 * n_p], flat[-1]

            if fixed:
                y = batch.target
            else:
                x_next = policy.transform(batch.next_robot, batch.next_humans, batch.next_mask)
                next_v = torch.func.functional_call(target_value, target, (x_next, batch.next_mask))
                y = td_targets(batch.reward, batch.done, next_v, gamma, dt, batch.robot[:, 7])
            x = policy.transform(batch.robot, batch.humans, batch.mask)

            def loss_of(ps: list[torch.Tensor]) -> torch.Tensor:
                v = torch.func.functional_call(
                    value, {**dict(zip(names, ps, strict=True)), **buffers}, (x, batch.mask)
                )
                return nn.functional.mse_loss(v, y.to(v.dtype))

            grads, loss = torch.func.grad_and_value(loss_of)(params)
            steps.add_(1)
            for i, (p, grad) in enumerate(zip(params, grads, strict=True)):
                t = steps[i].to(torch.float64)
                step_size = (lr / (1 - beta1**t)).to(p.dtype)
                bias_correction2_sqrt = torch.sqrt(1 - beta2**t).to(p.dtype)
                exp_avgs[i].lerp_(grad, 1 - beta1)
                exp_avg_sqs[i].mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
                denom = (exp_avg_sqs[i].sqrt() / bias_correction2_sqrt).add_(eps)
                p.sub_(step_size * exp_avgs[i] / denom)
            return (loss.detach(),)

        return step

    def _compile(self) -> None:
        self._ensure_state()
        idx = torch.zeros(self.batch_size, dtype=torch.long, device=self.memory.device)
        was_training = self.network.training
        self.network.train()
        try:
            with torch.no_grad():
                graph = make_fx(self._step_function(), tracing_mode="fake")(idx, *self._inputs)
        finally:
            self.network.train(was_training)
        options = {"cpp_wrapper": True} if self.memory.device.type == "cpu" else {}
        import torch._inductor as inductor  # noqa: PLC0415 - only a compiled run needs Inductor

        use_inductor_cache_of_these_kernels()

        self._compiled = inductor.compile(graph, [idx, *self._inputs], options=options)
        if self._use_graph:
            self._record_cuda_graph()

    def _mutated_inputs(self) -> list[torch.Tensor]:
        """The inputs the step writes: parameters, Adam's moments and the step counters."""
        n_p = len(self._params)
        at = len(self._inputs) - 1 - 2 * n_p
        return [*self._inputs[:n_p], *self._inputs[at:]]

    def _record_cuda_graph(self) -> None:
        """Records one compiled step as a CUDA graph over fixed input addresses.

        The step's inputs are the run's own tensors, updated in place; the indices are copied into
        ``_graph_idx``.
        """
        idx = torch.zeros(self.batch_size, dtype=torch.long, device=self.memory.device)
        mutated = self._mutated_inputs()
        saved = [t.clone() for t in mutated]
        side = torch.cuda.Stream(device=idx.device)
        side.wait_stream(torch.cuda.current_stream(idx.device))
        with torch.cuda.stream(side):  # warm-up off the capture: lazy loading, workspace allocation
            for _ in range(2):
                self._compiled(idx, *self._inputs)
        torch.cuda.current_stream(idx.device).wait_stream(side)
        with torch.no_grad():
            for t, value in zip(mutated, saved, strict=True):
                t.copy_(value)
        graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(graph):
            loss = self._compiled(idx, *self._inputs)[0]
        self._graph, self._graph_idx, self._graph_loss = graph, idx, loss

    # -- the step -------------------------------------------------------------------------------------

    def __call__(self, idx: torch.Tensor) -> torch.Tensor:
        """One gradient step on memory slots ``idx``.

        Args:
            idx: (batch_size,) int64 memory slots.

        Returns:
            The minibatch loss before the update (0-d tensor, not synchronised).

        Raises:
            ValueError: ``idx`` is not of the compiled batch size.
        """
        if idx.shape != (self.batch_size,):
            raise ValueError(
                f"the fused step was compiled for {self.batch_size} indices, got {tuple(idx.shape)}"
            )
        if self.optimizer.state is not self._state_seen:  # load_state_dict replaced it (a resume)
            self._ensure_state()
            if self._use_graph:
                self._record_cuda_graph()  # the moments and counters are new tensors
        if self._graph is not None:
            self._graph_idx.copy_(idx, non_blocking=True)
            self._graph.replay()
            return self._graph_loss.clone()  # the caller keeps a burst of losses: not the graph's buffer
        return self._compiled(idx, *self._inputs)[0]
