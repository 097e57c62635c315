"""An ExecuteMove action server and client on one executor spun on a thread of its own, over real DDS in a
context of their own: what the tests of crane_msgs_py's action classes share."""
import threading
from contextlib import contextmanager


@contextmanager
def served(server_class, client_class, name: str, execute, executor_class, **server_kwargs):
    """``with served(...) as (server_node, client):`` the server ``server_class(node, ExecuteMove, name,
    execute, **server_kwargs)`` on node ``<name>_server`` and a ``client_class`` client of it on
    ``<name>_client``, the server found; everything destroyed and shut down afterwards."""
    import rclpy
    from crane_interfaces.action import ExecuteMove

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        server_node = rclpy.create_node(f'{name}_server', context=context)
        client_node = rclpy.create_node(f'{name}_client', context=context)
        server = server_class(server_node, ExecuteMove, name, execute, **server_kwargs)
        client = client_class(client_node, ExecuteMove, name)
        executor = executor_class(context=context)
        executor.add_node(server_node)
        executor.add_node(client_node)
        stop = threading.Event()
        spin = threading.Thread(target=lambda: [executor.spin_once(0.05) for _ in iter(stop.is_set, True)])
        spin.start()
        try:
            assert client.wait_for_server(timeout_sec=20.0)
            yield server_node, client
        finally:
            stop.set()
            spin.join()
            server.destroy()
            client.destroy()
            executor.shutdown()
    finally:
        rclpy.shutdown(context=context)


def wait(future, timeout: float = 10.0):
    """The future's result, once done within ``timeout`` s (else the test fails)."""
    event = threading.Event()
    future.add_done_callback(lambda _: event.set())
    assert event.wait(timeout), 'the future never completed (its response was dropped?)'
    return future.result()
