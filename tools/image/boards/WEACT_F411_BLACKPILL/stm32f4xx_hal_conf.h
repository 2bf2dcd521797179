// The HAL configuration of MicroPython's own WEACT_F411_BLACKPILL board folder.
#include "boards/WEACT_F411_BLACKPILL/stm32f4xx_hal_conf.h"
