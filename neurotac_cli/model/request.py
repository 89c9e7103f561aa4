"""Checks of a model request's options, before any input is read or torch is imported."""

from neurotac_cli.errors import UsageError


def check_request(*, model_path=None, cv=None, model_spec=None, grid=(), plot=None, hyperparameters=None) -> None:
    """Refuse a request whose options contradict each other, before any input is read."""
    if grid and not cv:
        raise UsageError("--grid needs --cv and --model-spec (a grid of cross-validated models)")
    if (model_path is None) == (cv is None):
        raise UsageError("give either --model FILE, or --cv with --model-spec NAME")
    if cv and not model_spec:
        raise UsageError("--cv needs --model-spec NAME (the model trained per fold)")
    if grid and plot:
        raise UsageError("--plot draws one model; drop --grid, or plot the chosen point with its options (--layers 4 ...)")
    if model_path and any(value is not None for value in (hyperparameters or {}).values()):
        raise UsageError("hyperparameter options apply to --cv --model-spec only; a model file carries its own")
