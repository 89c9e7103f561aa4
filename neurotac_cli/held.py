"""Ctrl-C and SIGTERM held back while a verb starts: the standard library alone, so that holding
them begins before numpy, pyarrow or torch are imported."""


class HeldSignals:
    """Ctrl-C and SIGTERM held back while a model loads beside the main thread, then acted on: raised
    in the main thread while both threads import (torch, pandas), they left modules half made and
    the loader waiting on an import lock for ever, or a traceback, or the signal lost (a run to the
    end). `deliver` (the loader, once `done`) sends a held signal again, now to be acted on where the
    main thread waits for input; `restore` (the caller, after the load) puts the handlers back and
    acts on one still held. Signals are handled in the main thread only: elsewhere nothing is held.

    A verb begins holding them before its own imports (numpy's and pyarrow's, 0.1 s and more), where
    a Ctrl-C could be lost inside an extension's import and the run went on to its end, and hands the
    hold to `model.store.load_in_background` (`with HeldSignals() as signals:` around the imports:
    a verb that fails there ends the hold, `release`, and acts on a signal held so far)."""

    NUMBERS = ("SIGINT", "SIGTERM")

    def __init__(self):
        import signal
        import threading

        self.done, self.held, self.previous = threading.Event(), [], {}
        if threading.current_thread() is threading.main_thread():
            for name in self.NUMBERS:
                number = getattr(signal, name)
                self.previous[number] = signal.signal(number, self._handler)

    def _handler(self, number, frame):
        import os
        import signal

        if self.previous.get(number) == signal.SIG_IGN:  # ignored before the hold (a shell's background job's Ctrl-C)
            return None
        if not self.done.is_set():
            self.held.append(number)
            return None
        action = self.previous[number]
        if callable(action):
            return action(number, frame)
        signal.signal(number, signal.SIG_DFL)  # the default (SIG_IGN never gets here): end as the signal ends a process
        os.kill(os.getpid(), number)
        return None

    def deliver(self):
        import os

        if self.held:
            os.kill(os.getpid(), self.held.pop())

    def restore(self):
        import signal

        for number, action in self.previous.items():
            if signal.getsignal(number) == self._handler:
                signal.signal(number, action)
        if self.held:
            self._handler(self.held.pop(), None)

    def __enter__(self):
        return self

    def __exit__(self, kind, error, trace):
        if kind is not None:  # the verb failed before a load took the hold over
            self.release()
        return False

    def end(self) -> int | None:
        """End the hold without acting: the handlers put back, and the signal held first (None where
        none came), for the caller to end on as it would have."""
        number = self.held[0] if self.held else None
        self.held.clear()
        self.release()
        return number

    def release(self):
        """End the hold without a load: act on a signal held so far, as the handlers put back do."""
        self.done.set()
        self.restore()
