"""Small case files written by the tests: a 2D rectangle falling on the plane y = -gap."""


def falling_rectangle(
    cells: tuple[int, int] = (4, 4),
    size: tuple[float, float] = (1.0, 1.0),
    young: float = 1.0,
    tag: str = "ymin",
    contact_extra: str = "",
    dt: float = 0.005,
    T: float = 0.05,
) -> str:
    """The TOML of a rectangle (Q1, nu = 0.3, rho = 1) moving at (0, -1) towards the plane
    y = -0.01; ``contact_extra`` is appended to the ``[contact]`` table (e.g. a friction line)."""
    return (
        f'[mesh]\ngenerator = "rectangle"\ncells = [{cells[0]}, {cells[1]}]\nsize = [{size[0]}, {size[1]}]\n'
        f"[material]\nrho = 1.0\nE = {young}\nnu = 0.3\n"
        f'[contact]\ntag = "{tag}"\nobstacle = {{ type = "plane", point = [0.0, -0.01], normal = [0.0, 1.0] }}\n'
        f"{contact_extra}"
        "[initial]\nvelocity = [0.0, -1.0]\n"
        f"[time]\ndt = {dt}\nT = {T}\n"
    )
