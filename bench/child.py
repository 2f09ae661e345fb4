"""One batch of a benchmark in a child process, so that a crash shows as a signal and a hang as a batch killed."""


def run_child(ctx, target, args, timeout):
    """Run ``target(*args, conn)`` in a child of ``ctx`` and take what it sends on ``conn`` within ``timeout`` s:
    (the result or None, whether it hung and was killed, its exit code)."""
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=target, args=(*args, send))
    child.start()
    send.close()
    try:
        result = receive.recv() if receive.poll(timeout) else None
    except EOFError:  # the child died without an answer
        result = None
    hung = child.is_alive() and result is None
    if hung:
        child.kill()
    child.join(30)
    return result, hung, child.exitcode
