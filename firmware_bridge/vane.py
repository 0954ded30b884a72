"""Wind vane: the raw ``ADC.read_u16()`` value, averaged; the host turns it into a direction."""


class Vane:
    """Averages ``n`` readings of ``adc.read_u16()`` into one integer (0..65535)."""

    def __init__(self, adc, n=8):
        self._adc = adc
        self._n = n

    def read(self):
        total = 0
        read = self._adc.read_u16
        for _ in range(self._n):
            total += read()
        return (total + self._n // 2) // self._n
