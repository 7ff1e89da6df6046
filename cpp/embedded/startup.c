/* Start-up code of the dampnet firmware (Cortex-M, QEMU mps2-an386 / mps2-an500): the vector
 * table, the reset handler (copy .data, zero .bss, enable the FPU, run .init_array, main) and
 * semihosting's exit. Faults end the run with exit code 99 (QEMU's exit status 1). */
#include <stdint.h>

extern uint32_t __stack_top, __data_load, __data_start, __data_end, __bss_start, __bss_end;
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);
int main(void);
void dn_fw_exit(int code);

void Reset_Handler(void) {
  const uint32_t* src = &__data_load;
  for (uint32_t* dst = &__data_start; dst < &__data_end;) *dst++ = *src++;
  for (uint32_t* dst = &__bss_start; dst < &__bss_end;) *dst++ = 0;
  *(volatile uint32_t*)0xE000ED88 |= 0xFu << 20; /* CPACR: CP10 and CP11 (the FPU) full access */
  __asm volatile("dsb\n\tisb" ::: "memory");
  for (void (**f)(void) = __init_array_start; f < __init_array_end; ++f) (*f)();
  dn_fw_exit(main());
}

void Fault_Handler(void) { dn_fw_exit(99); }

__attribute__((section(".vectors"), used)) void (*const dn_fw_vectors[16])(void) = {
    (void (*)(void))(uintptr_t)&__stack_top, /* initial SP */
    Reset_Handler, Fault_Handler /* NMI */, Fault_Handler /* HardFault */,
    Fault_Handler /* MemManage */, Fault_Handler /* BusFault */, Fault_Handler /* UsageFault */,
    0, 0, 0, 0, Fault_Handler /* SVC */, Fault_Handler /* DebugMon */, 0,
    Fault_Handler /* PendSV */, Fault_Handler /* SysTick */};

/* Semihosting (the debugger's, here QEMU's, services through BKPT 0xAB). */
int dn_fw_semihost(int op, const void* arg) {
  register int r0 __asm__("r0") = op;
  register const void* r1 __asm__("r1") = arg;
  __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}

void dn_fw_exit(int code) {
  const uint32_t block[2] = {0x20026u /* ADP_Stopped_ApplicationExit */, (uint32_t)code};
  dn_fw_semihost(0x20 /* SYS_EXIT_EXTENDED */, block);
  for (;;) {
  }
}
