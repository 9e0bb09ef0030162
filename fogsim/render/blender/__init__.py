"""The Blender side: scene description → bpy objects, Cycles passes, the render job and the
add-on's panel. The only code in fogsim that imports bpy (Blender 3.4 binary or the 5.0 module)."""


def _thread_lock_for_tqdm() -> None:
    """tqdm's default write lock holds a multiprocessing semaphore, and a Blender 3.4 process in
    which one exists segfaults at exit (in ``addon_utils.disable_all``) — a script that ends
    normally, or the user quitting Blender after the add-on rendered. fogsim's bars are written
    from one process, so a thread lock is all they need."""
    import threading

    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())


_thread_lock_for_tqdm()
